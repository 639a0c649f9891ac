#include "column_hint.hpp"

#include <algorithm>
#include <cctype>

namespace csympnet::csv_detail {

namespace {

// Lower-case tokens of a name: split at anything not a letter or digit, and at a lower-to-upper
// case change ("cartVel" -> "cart", "vel").
std::vector<std::string> tokens_of(std::string_view name) {
  std::vector<std::string> out;
  std::string cur;
  char prev = 0;
  for (char c : name) {
    const auto u = static_cast<unsigned char>(c);
    if (!std::isalnum(u)) {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      if (std::isupper(u) && std::islower(static_cast<unsigned char>(prev)) && !cur.empty()) {
        out.push_back(cur);
        cur.clear();
      }
      cur += static_cast<char>(std::tolower(u));
    }
    prev = c;
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

bool letter_then_digits(const std::string& t, char letter) {
  return t.size() >= 2 && t[0] == letter &&
         std::all_of(t.begin() + 1, t.end(), [](char c) { return c >= '0' && c <= '9'; });
}

bool ends_with(const std::string& t, std::string_view suffix) {
  return t.size() >= suffix.size() &&
         t.compare(t.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

ColumnRole guess_column_role(std::string_view name) {
  const std::vector<std::string> toks = tokens_of(name);
  for (const std::string& t : toks)
    if (t == "traj" || t == "trajectory") return ColumnRole::kTraj;
  if (!toks.empty() && (toks[0] == "t" || toks[0] == "time" || toks[0] == "timestamp" ||
                        toks[0] == "times" || toks[0] == "timestamps"))
    return ColumnRole::kTime;
  for (const std::string& t : toks)
    if (t == "v" || t == "vel" || t == "velocity" || t == "velocities" || t == "speed" ||
        t == "omega" || t == "p" || t == "mom" || t == "momentum" || t == "momenta" || t == "dot" ||
        ends_with(t, "dot") || letter_then_digits(t, 'v') || letter_then_digits(t, 'p'))
      return ColumnRole::kMomentum;
  return ColumnRole::kPosition;
}

std::string columns_example(const std::vector<std::string_view>& fields) {
  if (fields.size() < 2 || fields.size() > 81) return "--columns t=TIME,q1=POSITION";
  std::vector<std::string> names;
  for (std::string_view f : fields)
    names.emplace_back(f.empty() ? std::string("COLUMN") : std::string(f.substr(0, 40)));
  std::vector<ColumnRole> roles;
  for (std::string_view f : fields) roles.push_back(guess_column_role(f));
  // One time and at most one traj column; the first column is the time when none is named so.
  std::size_t time = std::find(roles.begin(), roles.end(), ColumnRole::kTime) - roles.begin();
  if (time == roles.size()) time = 0;
  std::size_t traj = roles.size();
  for (std::size_t c = 0; c < roles.size(); ++c)
    if (c != time && roles[c] == ColumnRole::kTraj && traj == roles.size()) traj = c;
  std::vector<std::size_t> q, p;
  for (std::size_t c = 0; c < roles.size(); ++c) {
    if (c == time || c == traj) continue;
    (roles[c] == ColumnRole::kMomentum ? p : q).push_back(c);
  }
  // Momenta only beside as many positions; otherwise every other column is a position.
  if (p.size() != q.size()) {
    q.insert(q.end(), p.begin(), p.end());
    std::sort(q.begin(), q.end());
    p.clear();
  }
  if (q.empty()) return "--columns t=TIME,q1=POSITION";
  std::string out = "--columns ";
  if (traj < names.size()) out += "traj=" + names[traj] + ",";
  out += "t=" + names[time];
  for (std::size_t i = 0; i < q.size(); ++i)
    out += ",q" + std::to_string(i + 1) + "=" + names[q[i]];
  for (std::size_t i = 0; i < p.size(); ++i)
    out += ",p" + std::to_string(i + 1) + "=" + names[p[i]];
  return out;
}

}  // namespace csympnet::csv_detail
