#include "csympnet/data/csv.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "column_hint.hpp"
#include "csv_text.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/io/files.hpp"

namespace csympnet {

using csv_detail::at;
using csv_detail::columns_example;
using csv_detail::CsvText;
using csv_detail::Line;
using csv_detail::quote;

namespace {

constexpr const char* kPairsForm = "h,q1..qd,p1..pd,next_q1..next_qd,next_p1..next_pd";
constexpr const char* kTrajForm = "[traj,]t,q1..qd,p1..pd";
constexpr const char* kPositionsForm = "[traj,]t,q1..qd";

std::string shortest(double v) {
  return round_trip_text(v);
}

struct Header {
  CsvKind kind = CsvKind::kPairs;
  bool has_traj = false;
  Index d = 0;
  Index m = 0;  // known inputs u1..um (trajectories and positions only)
  std::vector<std::string> names;
};

std::vector<std::string> numbered(const std::string& prefix, Index d) {
  std::vector<std::string> v;
  for (Index i = 1; i <= d; ++i) v.push_back(prefix + std::to_string(i));
  return v;
}

std::vector<std::string> header_names(CsvKind kind, Index d, bool has_traj, Index m = 0) {
  std::vector<std::string> names;
  auto add = [&](const std::vector<std::string>& v) {
    names.insert(names.end(), v.begin(), v.end());
  };
  if (kind == CsvKind::kPairs) {
    names.push_back("h");
    for (const char* g : {"q", "p", "next_q", "next_p"}) add(numbered(g, d));
  } else {
    if (has_traj) names.push_back("traj");
    names.push_back("t");
    add(numbered("q", d));
    if (kind == CsvKind::kTrajectories) add(numbered("p", d));
    add(numbered("u", m));
  }
  return names;
}

// The group ("q", "p", "next_q", "next_p") of a column name like "next_q3", or "" if none.
std::string_view group_of(std::string_view name) {
  const std::size_t digits = name.find_first_of("0123456789");
  if (digits == std::string_view::npos || digits == 0 ||
      name.find_first_not_of("0123456789", digits) != std::string_view::npos)
    return {};
  const std::string_view g = name.substr(0, digits);
  return g == "q" || g == "p" || g == "next_q" || g == "next_p" || g == "u" ? g
                                                                            : std::string_view();
}

// How many columns of each group the header has, wherever they are; used to explain a
// header whose shape is wrong rather than just its first bad name.
std::unordered_map<std::string_view, Index> group_counts(
    const std::vector<std::string_view>& fields) {
  std::unordered_map<std::string_view, Index> n{
      {"q", 0}, {"p", 0}, {"next_q", 0}, {"next_p", 0}, {"u", 0}};
  for (std::string_view s : fields)
    if (const std::string_view g = group_of(s); !g.empty()) ++n[g];
  return n;
}

Header parse_header(const CsvText& f) {
  const std::vector<std::string_view> fields = csv_detail::split_fields(f.lines[0].text);
  const std::string where = at(f.path, f.lines[0].number);
  Header h;
  if (fields[0] == "h") {
    h.kind = CsvKind::kPairs;
  } else if (fields[0] == "t" || fields[0] == "traj") {
    h.kind = CsvKind::kTrajectories;
    h.has_traj = fields[0] == "traj";
  } else {
    throw Error(where + "unrecognised header " + quote(f.lines[0].text) +
                "; expected a pairs header '" + kPairsForm + "' (d=1: 'h,q1,p1,next_q1,next_p1')" +
                " or a trajectories header '" + kTrajForm +
                "' (d=1: 'traj,t,q1,p1' or 't,q1,p1'), or positions alone '" + kPositionsForm +
                "' (csympnet fit fits the momenta as hidden states), or name your columns with "
                "--columns, e.g. " +
                columns_example(fields));
  }
  // A name given twice would be counted twice below (two q1 read as d = 2).
  for (std::size_t c = 0; c < fields.size(); ++c)
    for (std::size_t k = 0; k < c; ++k)
      if (fields[k] == fields[c] && !fields[c].empty())
        throw Error(where + "header column " + std::to_string(c + 1) + " " + quote(fields[c]) +
                    " repeats column " + std::to_string(k + 1) +
                    "; expected each column name once, as '" +
                    (h.kind == CsvKind::kPairs ? kPairsForm : kTrajForm) + "'");
  auto n = group_counts(fields);
  const Index fixed = h.kind == CsvKind::kPairs ? 1 : (h.has_traj ? 2 : 1);
  const Index cols = static_cast<Index>(fields.size());
  if (h.kind == CsvKind::kPairs && n["u"] > 0)
    throw Error(where + "pairs header " + quote(f.lines[0].text) + " has " +
                std::to_string(n["u"]) +
                " input columns (u...); a pair carries no inputs: expected '" + kPairsForm +
                "', or a driven record as a trajectories file '" + kTrajForm +
                ",u1..um' or positions '" + kPositionsForm + ",u1..um'");
  h.m = n["u"];
  // Positions alone: '[traj,]t,q1..qd' (the momenta are then hidden states of the fit).
  if (h.kind == CsvKind::kTrajectories && n["q"] >= 1 && n["p"] == 0 && n["next_q"] == 0 &&
      n["next_p"] == 0 && cols == fixed + n["q"] + h.m)
    h.kind = CsvKind::kPositions;
  const Index groups = h.kind == CsvKind::kPairs ? 4 : (h.kind == CsvKind::kPositions ? 1 : 2);
  h.d = n["q"];
  bool shape_ok = h.d >= 1 && cols == fixed + groups * h.d + h.m &&
                  (h.kind == CsvKind::kPositions || n["p"] == h.d);
  if (h.kind == CsvKind::kPairs) shape_ok = shape_ok && n["next_q"] == h.d && n["next_p"] == h.d;
  if (!shape_ok) {
    // Columns of no group beside a header that is right without them (a 'temp' column, a
    // trailing comma's empty name): named, with the --columns that reads the others.
    std::vector<std::string_view> known;
    std::size_t first_unknown = fields.size();
    for (std::size_t c = 0; c < fields.size(); ++c) {
      const bool fixed_name = fields[c] == "h" || fields[c] == "t" || fields[c] == "traj";
      if (fixed_name || !group_of(fields[c]).empty())
        known.push_back(fields[c]);
      else if (first_unknown == fields.size())
        first_unknown = c;
    }
    auto kn = group_counts(known);
    const auto known_cols = static_cast<Index>(known.size());
    bool known_ok =
        kn["q"] >= 1 && kn["p"] == kn["q"] && known_cols == fixed + groups * kn["q"] + kn["u"];
    if (h.kind == CsvKind::kPairs)
      known_ok = known_ok && kn["next_q"] == kn["q"] && kn["next_p"] == kn["q"];
    if (known_ok && first_unknown < fields.size()) {
      std::string map;
      for (std::string_view k : known)
        map += (map.empty() ? "" : ",") + std::string(k) + "=" + std::string(k);
      const std::string_view bad = fields[first_unknown];
      throw Error(
          where + "header column " + std::to_string(first_unknown + 1) + " " +
          (bad.empty() ? std::string("is empty (a trailing comma?)")
                       : quote(bad) + " is not a column csympnet reads") +
          "; expected only the columns '" + (h.kind == CsvKind::kPairs ? kPairsForm : kTrajForm) +
          "', or --columns naming the ones to read (it drops the others): --columns " + map);
    }
    if (h.kind == CsvKind::kPairs && n["q"] >= 1 && n["p"] == 0 && n["next_p"] == 0)
      throw Error(where + "pairs header " + quote(f.lines[0].text) +
                  " has positions but no momenta: a pair needs a whole state, q and p, at both "
                  "ends; expected '" +
                  kPairsForm + "', or positions alone as a trajectories file '" + kPositionsForm +
                  "' (the momenta are then fitted as hidden states)");
    std::string counts = std::to_string(n["q"]) + " q and " + std::to_string(n["p"]) + " p";
    if (h.kind == CsvKind::kPairs)
      counts += " and " + std::to_string(n["next_q"]) + " next_q and " +
                std::to_string(n["next_p"]) + " next_p";
    // No column named as csympnet names them beside t: the user's own names, read with
    // --columns (positions unless their names say otherwise).
    const bool own_names = h.kind == CsvKind::kTrajectories && n["q"] == 0 && n["p"] == 0;
    throw Error(where + (h.kind == CsvKind::kPairs ? "pairs" : "trajectories") + " header " +
                quote(f.lines[0].text) + " has " + std::to_string(cols) + " columns with " +
                counts + " columns; expected the same number d >= 1 of each, as '" +
                (h.kind == CsvKind::kPairs ? kPairsForm : kTrajForm) + "'" +
                (own_names
                     ? std::string(", or positions alone '") + kPositionsForm +
                           "', or --columns naming your columns, e.g. " + columns_example(fields)
                     : std::string()));
  }
  h.names = header_names(h.kind, h.d, h.has_traj, h.m);
  const char* form = h.kind == CsvKind::kPairs       ? kPairsForm
                     : h.kind == CsvKind::kPositions ? kPositionsForm
                                                     : kTrajForm;
  for (std::size_t c = 0; c < fields.size(); ++c)
    if (fields[c] != h.names[c])
      throw Error(where + "header column " + std::to_string(c + 1) + " is " + quote(fields[c]) +
                  "; expected '" + h.names[c] + "' (columns must be exactly, in order, '" + form +
                  "', case-sensitive)");
  return h;
}

// Checks every data row for blank lines and field count, then hands the fields on.
template <typename RowFn>
void for_each_row(const CsvText& f, const Header& h, RowFn&& row) {
  if (f.lines.size() < 2)
    throw Error(at(f.path, f.lines[0].number) +
                "header only, no data rows; expected at least one data row after the header");
  for (std::size_t k = 1; k < f.lines.size(); ++k) {
    if ((k & 0xFFFF) == 0) throw_if_stop_requested("reading " + f.path);
    const Line& line = f.lines[k];
    if (csv_detail::is_blank(line.text))
      throw Error(at(f.path, line.number) +
                  "blank line; expected a data row (blank lines are allowed only at the end)");
    const std::vector<std::string_view> fields = csv_detail::split_fields(line.text);
    if (fields.size() != h.names.size())
      throw Error(at(f.path, line.number) + "found " + std::to_string(fields.size()) +
                  " fields; expected " + std::to_string(h.names.size()) + " as in the header");
    row(line, fields);
  }
}

double field_value(const CsvText& f, const Line& line, const Header& h, std::size_t c,
                   std::string_view field) {
  double v = 0;
  std::string why;
  if (!csv_detail::parse_finite_double(field, v, why))
    throw Error(at(f.path, line.number) + "column '" + h.names[c] +
                "': expected a finite number, got " + why);
  return v;
}

// Data read for training (read_any_as_pairs) enters squared losses; beyond this magnitude a
// state's or step's square overflows double and training could only diverge, so such values are
// refused at their line. The other readers keep the full range of double (their round trip is
// exact for every finite value). Times are only differenced; they are checked as steps.
constexpr double kMaxTrainingMagnitude = 1e150;

double state_value(const CsvText& f, const Line& line, const Header& h, std::size_t c,
                   std::string_view field, bool for_training) {
  const double v = field_value(f, line, h, c, field);
  if (for_training && std::abs(v) > kMaxTrainingMagnitude)
    throw Error(at(f.path, line.number) + "column '" + h.names[c] + "': " + quote(field) +
                " is too large to train on (its square overflows double); expected |value| "
                "<= 1e150");
  return v;
}

Header require_kind(const CsvText& f, CsvKind kind) {
  Header h = parse_header(f);
  if (h.kind == CsvKind::kPositions && kind == CsvKind::kTrajectories)
    throw Error(at(f.path, 1) + "trajectories header " + quote(f.lines[0].text) +
                " has positions but no momenta; expected '" + kTrajForm +
                "' here (csympnet fit, Python's identify and CSympNetID also take positions "
                "alone, '" +
                kPositionsForm + "', and fit the momenta as hidden states)");
  const auto what = [](CsvKind k) {
    return k == CsvKind::kPairs       ? std::string("pairs header '") + kPairsForm + "'"
           : k == CsvKind::kPositions ? std::string("positions header '") + kPositionsForm + "'"
                                      : std::string("trajectories header '") + kTrajForm + "'";
  };
  if (h.kind != kind)
    throw Error(at(f.path, 1) + "this file has a " + what(h.kind) + "; expected a " + what(kind));
  return h;
}

PairSet read_pairs(const CsvText& f, bool for_training = false) {
  const Header h = require_kind(f, CsvKind::kPairs);
  const Index dim = 2 * h.d;
  std::vector<double> hs, z0, z1;
  for_each_row(f, h, [&](const Line& line, const std::vector<std::string_view>& fields) {
    const double step = state_value(f, line, h, 0, fields[0], for_training);
    if (!(step > 0))
      throw Error(at(f.path, line.number) + "column 'h': expected a step h > 0, got " +
                  quote(fields[0]));
    if (step < std::numeric_limits<double>::min())
      throw Error(at(f.path, line.number) + "column 'h': the step " + quote(fields[0]) +
                  " is below the smallest normal double (2.2e-308), where it has lost its "
                  "digits; expected a larger step (rescale time)");
    hs.push_back(step);
    for (Index i = 0; i < dim; ++i) {
      const auto c0 = static_cast<std::size_t>(1 + i), c1 = static_cast<std::size_t>(1 + dim + i);
      z0.push_back(state_value(f, line, h, c0, fields[c0], for_training));
      z1.push_back(state_value(f, line, h, c1, fields[c1], for_training));
    }
  });
  const auto n = static_cast<Index>(hs.size());
  PairSet p;
  // Rows were stored sample by sample, i.e. column-major for a 2d x N matrix.
  p.z0 = Eigen::Map<const Matrix>(z0.data(), dim, n);
  p.z1 = Eigen::Map<const Matrix>(z1.data(), dim, n);
  p.h = Eigen::Map<const Vector>(hs.data(), n);
  return p;
}

std::vector<Trajectory> read_trajectories(const CsvText& f, bool for_training = false,
                                          CsvKind kind = CsvKind::kTrajectories,
                                          InputColumns inputs = InputColumns::kRefuse) {
  const Header h = require_kind(f, kind);
  if (h.m > 0 && inputs == InputColumns::kRefuse)
    throw Error(at(f.path, 1) + "the header " + quote(f.lines[0].text) + " has " +
                std::to_string(h.m) +
                " input columns (u1..um), which this command does not read; expected a "
                "record without inputs, '" +
                (kind == CsvKind::kPositions ? "[traj,]t,q1..qd" : "[traj,]t,q1..qd,p1..pd") +
                "' (records with known inputs are read by csympnet fit and evaluate, Python's "
                "identify and CSympNetID, with the library core)");
  const Index dim = kind == CsvKind::kPositions ? h.d : 2 * h.d;
  const std::size_t tcol = h.has_traj ? 1 : 0;

  struct Pending {
    long long id = 0;
    std::size_t first_line = 0, last_line = 0;
    std::vector<double> t, z, u;
  };
  std::vector<Pending> done;
  Pending cur;
  bool started = false;
  std::unordered_map<long long, std::size_t> seen;  // id -> index in `done` (closed runs)
  std::string id_text;                              // the current id as written

  for_each_row(f, h, [&](const Line& line, const std::vector<std::string_view>& fields) {
    long long id = 0;
    if (h.has_traj && !csv_detail::parse_integer(fields[0], id))
      throw Error(at(f.path, line.number) +
                  "column 'traj': expected an integer trajectory id, got " + quote(fields[0]));
    // Ids are integers, so '-0' and '0' (or '01' and '1') are one id: written differently on
    // neighbouring rows they were most likely meant as two trajectories. Say so, rather than
    // merge them and report the restarted time.
    if (h.has_traj && started && id == cur.id && fields[0] != id_text)
      throw Error(at(f.path, line.number) + "column 'traj': id " + quote(fields[0]) +
                  " is the same integer as " + quote(id_text) + " on line " +
                  std::to_string(cur.last_line) +
                  " but written differently; expected each trajectory's id written one way "
                  "(distinct trajectories need distinct integers)");
    if (h.has_traj) id_text = std::string(fields[0]);
    if (!started || id != cur.id) {
      if (started) {
        seen[cur.id] = done.size();
        done.push_back(std::move(cur));
      }
      if (auto it = seen.find(id); it != seen.end()) {
        const Pending& old = done[it->second];
        throw Error(at(f.path, line.number) + "mismatched trajectory ids: id " +
                    std::to_string(id) + " reappears after its rows on lines " +
                    std::to_string(old.first_line) + "-" + std::to_string(old.last_line) +
                    "; expected the rows of each trajectory to be contiguous");
      }
      cur = Pending{id, line.number, line.number, {}, {}, {}};
      started = true;
    }
    const double t = field_value(f, line, h, tcol, fields[tcol]);
    if (!cur.t.empty() && !(t > cur.t.back()))
      throw Error(at(f.path, line.number) + "column 't': got " + quote(fields[tcol]) +
                  " after t = " + shortest(cur.t.back()) + " on line " +
                  std::to_string(cur.last_line) +
                  "; expected times to strictly increase within a trajectory");
    if (!cur.t.empty() && t - cur.t.back() < std::numeric_limits<double>::min())
      throw Error(at(f.path, line.number) +
                  "column 't': the step from t = " + shortest(cur.t.back()) + " on line " +
                  std::to_string(cur.last_line) + " to " + quote(fields[tcol]) +
                  " is below the smallest normal double (2.2e-308); expected a larger step "
                  "(rescale time)");
    // Every consumer uses the steps t[n] - t[n-1]; one that overflows is an error here, at
    // its line, rather than an infinite step later.
    if (!cur.t.empty() && !std::isfinite(t - cur.t.back()))
      throw Error(at(f.path, line.number) +
                  "column 't': the step from t = " + shortest(cur.t.back()) + " on line " +
                  std::to_string(cur.last_line) + " to " + quote(fields[tcol]) +
                  " overflows double; expected times whose differences are finite");
    cur.t.push_back(t);
    cur.last_line = line.number;
    for (Index i = 0; i < dim; ++i) {
      const auto c = tcol + 1 + static_cast<std::size_t>(i);
      cur.z.push_back(state_value(f, line, h, c, fields[c], for_training));
    }
    for (Index j = 0; j < h.m; ++j) {
      const auto c = tcol + 1 + static_cast<std::size_t>(dim + j);
      cur.u.push_back(state_value(f, line, h, c, fields[c], for_training));
    }
  });
  done.push_back(std::move(cur));

  std::vector<Trajectory> out;
  out.reserve(done.size());
  for (const Pending& p : done) {
    const auto n = static_cast<Index>(p.t.size());
    Trajectory tr;
    tr.t = Eigen::Map<const Vector>(p.t.data(), n);
    tr.z = Eigen::Map<const Matrix>(p.z.data(), dim, n);
    if (h.m > 0) tr.u = Eigen::Map<const Matrix>(p.u.data(), h.m, n);
    out.push_back(std::move(tr));
  }
  return out;
}

void append_double(std::string& out, double v) {
  out += round_trip_text(v);
}

void append_header(std::string& out, const std::vector<std::string>& names) {
  for (std::size_t c = 0; c < names.size(); ++c) {
    if (c > 0) out += ',';
    out += names[c];
  }
  out += '\n';
}

PairSet any_as_pairs(const CsvText& f) {
  if (parse_header(f).kind == CsvKind::kPairs) return read_pairs(f, true);
  const std::vector<Trajectory> trajs = read_trajectories(f, true);
  Index pairs = 0;
  for (const Trajectory& tr : trajs) pairs += tr.steps();
  if (pairs == 0)
    throw Error(f.path + ": all " + std::to_string(trajs.size()) +
                " trajectories have a single row, so the file gives no pairs; expected at "
                "least one trajectory with two or more rows");
  return pairs_from_trajectories(trajs);
}

}  // namespace

CsvKind detect_csv_kind(const std::string& path) {
  return parse_header(csv_detail::load_csv_text(path)).kind;
}

CsvInput read_csv_input(const std::string& path) {
  CsvInput in;
  in.name = path == "-" ? std::string("standard input") : path;
  in.text = read_text_file(path);
  const Header h = parse_header(csv_detail::csv_text_from_bytes(in.name, in.text));
  in.kind = h.kind;
  in.inputs = h.m;
  return in;
}

CsvInput read_csv_input(const std::string& path, const ColumnMap& map) {
  CsvInput in;
  in.name = path == "-" ? std::string("standard input") : path;
  std::string original = read_text_file(path);
  // The file's own header line, for messages about the header --columns made from it.
  const std::string own_header =
      original.substr(0, std::min(original.find('\n'), std::size_t{200}));
  in.text = apply_column_map(std::move(original), in.name, map);
  try {
    const Header h = parse_header(csv_detail::csv_text_from_bytes(in.name, in.text));
    in.kind = h.kind;
    in.inputs = h.m;
  } catch (const Error& e) {
    if (map.empty()) throw;
    // The parser quotes the header as --columns rewrote it, which the user never wrote.
    const std::string built = in.text.substr(0, in.text.find('\n'));
    std::string what = e.what();
    if (const std::size_t at = what.find(quote(built)); at != std::string::npos)
      what.replace(at, quote(built).size(),
                   quote(built) + " (the header --columns makes from the file's own " +
                       quote(!own_header.empty() && own_header.back() == '\r'
                                 ? own_header.substr(0, own_header.size() - 1)
                                 : own_header) +
                       ")");
    throw Error(what);
  }
  return in;
}

PairSet read_pairs_csv(const std::string& path) {
  return read_pairs(csv_detail::load_csv_text(path));
}

std::vector<Trajectory> read_trajectories_csv(const std::string& path) {
  return read_trajectories(csv_detail::load_csv_text(path));
}

PairSet parse_pairs_csv(std::string text, const std::string& name) {
  return read_pairs(csv_detail::csv_text_from_bytes(name, std::move(text)));
}

std::vector<Trajectory> parse_trajectories_csv(std::string text, const std::string& name,
                                               InputColumns inputs) {
  return read_trajectories(csv_detail::csv_text_from_bytes(name, std::move(text)), false,
                           CsvKind::kTrajectories, inputs);
}

std::vector<Trajectory> parse_positions_csv(std::string text, const std::string& name,
                                            InputColumns inputs) {
  return read_trajectories(csv_detail::csv_text_from_bytes(name, std::move(text)), true,
                           CsvKind::kPositions, inputs);
}

PairSet read_any_as_pairs(const std::string& path) {
  return any_as_pairs(csv_detail::load_csv_text(path));
}

PairSet parse_any_as_pairs(std::string text, const std::string& name) {
  return any_as_pairs(csv_detail::csv_text_from_bytes(name, std::move(text)));
}

std::string pairs_csv_text(const PairSet& pairs) {
  pairs.validate("pairs_csv_text");
  std::string out;
  append_header(out, header_names(CsvKind::kPairs, pairs.d(), false));
  for (Index j = 0; j < pairs.size(); ++j) {
    append_double(out, pairs.h(j));
    for (const Matrix* m : {&pairs.z0, &pairs.z1})
      for (Index i = 0; i < pairs.dim(); ++i) {
        out += ',';
        append_double(out, (*m)(i, j));
      }
    out += '\n';
  }
  return out;
}

std::string trajectories_csv_text(const std::vector<Trajectory>& trajs) {
  const std::string where = "trajectories_csv_text";
  require(!trajs.empty(), [&] { return where + ": no trajectories; expected at least one"; });
  const Index dim = trajs.front().z.rows(), m = trajs.front().u.rows();
  for (std::size_t k = 0; k < trajs.size(); ++k) {
    trajs[k].validate(where + ": trajectory " + std::to_string(k));
    require(trajs[k].z.rows() == dim && trajs[k].u.rows() == m, [&] {
      return where + ": trajectory " + std::to_string(k) + " has dimension " +
             std::to_string(trajs[k].z.rows()) + " and " + std::to_string(trajs[k].u.rows()) +
             " inputs; expected " + std::to_string(dim) + " and " + std::to_string(m);
    });
  }
  std::string out;
  append_header(out, header_names(CsvKind::kTrajectories, dim / 2, true, m));
  for (std::size_t k = 0; k < trajs.size(); ++k) {
    const Trajectory& tr = trajs[k];
    for (Index n = 0; n < tr.t.size(); ++n) {
      out += std::to_string(k);
      out += ',';
      append_double(out, tr.t(n));
      for (Index i = 0; i < dim; ++i) {
        out += ',';
        append_double(out, tr.z(i, n));
      }
      for (Index j = 0; j < m; ++j) {
        out += ',';
        append_double(out, tr.u(j, n));
      }
      out += '\n';
    }
  }
  return out;
}

// Validation errors name the path, so they are rethrown with it.
void write_pairs_csv(const std::string& path, const PairSet& pairs) {
  std::string text;
  try {
    text = pairs_csv_text(pairs);
  } catch (const Error& e) {
    throw Error("write_pairs_csv('" + path + "'): " + e.what());
  }
  write_text_atomic(path, text);
}

void write_trajectories_csv(const std::string& path, const std::vector<Trajectory>& trajs) {
  std::string text;
  try {
    text = trajectories_csv_text(trajs);
  } catch (const Error& e) {
    throw Error("write_trajectories_csv('" + path + "'): " + e.what());
  }
  write_text_atomic(path, text);
}

}  // namespace csympnet
