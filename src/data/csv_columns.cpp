// Column maps for CSV files with their own header names (csv.hpp: ColumnMap).
#include <algorithm>
#include <map>
#include <string>
#include <tuple>

#include "csv_text.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"

namespace csympnet {

namespace {

using csv_detail::quote;

// Where a canonical name sits in the canonical order: (group, index). Groups: traj, t, h, q, p,
// next_q, next_p, u (the known inputs, last). Returns false for any other name.
bool canonical_rank(const std::string& name, std::pair<int, long>& rank) {
  if (name == "traj") return rank = {0, 0}, true;
  if (name == "t") return rank = {1, 0}, true;
  if (name == "h") return rank = {2, 0}, true;
  static const std::pair<const char*, int> prefixes[] = {
      {"next_q", 5}, {"next_p", 6}, {"q", 3}, {"p", 4}, {"u", 7}};
  for (const auto& [prefix, group] : prefixes) {
    const std::string pre = prefix;
    if (name.rfind(pre, 0) != 0) continue;
    const std::string digits = name.substr(pre.size());
    if (digits.empty() || digits.size() > 6 || digits.front() == '0' ||
        !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return false;
    rank = {group, std::stol(digits)};
    return true;
  }
  return false;
}

std::string trimmed(std::string_view s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(" \t");
  return std::string(s.substr(b, e - b + 1));
}

}  // namespace

ColumnMap parse_column_map(const std::string& spec, const std::string& option) {
  ColumnMap map;
  if (spec.empty()) return map;  // no map: the header must be csympnet's own
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t end = std::min(spec.find(',', start), spec.size());
    const std::string entry = spec.substr(start, end - start);
    const std::size_t eq = entry.find('=');
    const std::string key = trimmed(entry.substr(0, eq == std::string::npos ? 0 : eq));
    const std::string value =
        eq == std::string::npos ? std::string() : trimmed(entry.substr(eq + 1));
    require(eq != std::string::npos && !key.empty() && !value.empty(), [&] {
      return option + ": " + quote(entry) +
             " is not NAME=COLUMN; expected entries like t=time,q1=theta,p1=omega";
    });
    std::pair<int, long> rank;
    require(canonical_rank(key, rank), [&] {
      return option + ": " + quote(key) +
             " is not a column csympnet reads; expected traj, t, h, q1..qd, p1..pd, "
             "next_q1..next_qd, next_p1..next_pd or the inputs u1..um before each '='";
    });
    // Plain pairs, not structured bindings: clang 14 (the fuzzing build) cannot capture
    // those in a lambda.
    for (const auto& kv : map.columns) {
      const std::string& k = kv.first;
      const std::string& v = kv.second;
      require(k != key, [&] { return option + ": " + key + " is mapped twice"; });
      require(v != value, [&] {
        return option + ": column " + quote(value) + " is mapped twice (to " + k + " and " + key +
               ")";
      });
    }
    map.columns.emplace_back(key, value);
    start = end + 1;
  }
  return map;
}

std::string apply_column_map(std::string text, const std::string& name, const ColumnMap& map) {
  if (map.empty()) return text;
  const csv_detail::CsvText f = csv_detail::csv_text_from_bytes(name, std::move(text));
  const csv_detail::Line& head = f.lines.front();
  const std::vector<std::string_view> fields = csv_detail::split_fields(head.text);
  const std::map<std::string, std::string> canonical_of = [&] {
    std::map<std::string, std::string> m;
    for (const auto& [key, value] : map.columns) m[value] = key;
    return m;
  }();
  // Each kept column: its canonical rank and name, and where it is in the file.
  std::vector<std::tuple<std::pair<int, long>, std::string, std::size_t>> kept;
  std::map<std::string, std::size_t> found;
  for (std::size_t c = 0; c < fields.size(); ++c) {
    const std::string field(fields[c]);
    std::string canonical;
    if (const auto it = canonical_of.find(field); it != canonical_of.end()) {
      canonical = it->second;
      require(found.emplace(field, c).second, [&] {
        return csv_detail::at(name, head.number) + "column " + quote(field) +
               " appears twice in the header; expected it once, as --columns maps it";
      });
    } else {
      std::pair<int, long> unused;
      const bool mapped_away = std::any_of(map.columns.begin(), map.columns.end(),
                                           [&](const auto& kv) { return kv.first == field; });
      if (!canonical_rank(field, unused) || mapped_away) continue;  // not read: dropped
      canonical = field;
    }
    std::pair<int, long> rank;
    canonical_rank(canonical, rank);
    kept.emplace_back(rank, canonical, c);
  }
  for (const auto& kv : map.columns) {
    const std::string& key = kv.first;
    const std::string& value = kv.second;
    require(found.count(value) == 1, [&] {
      std::string names;
      for (std::size_t c = 0; c < fields.size(); ++c)
        names += (c == 0 ? "" : ", ") + quote(fields[c]);
      return csv_detail::at(name, head.number) + "--columns maps " + key + " to " + quote(value) +
             ", which is not a column of the header; expected one of " + names;
    });
  }
  std::stable_sort(kept.begin(), kept.end(),
                   [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });

  std::string out;
  std::size_t line_number = 0;
  for (const csv_detail::Line& line : f.lines) {
    while (++line_number < line.number) out += '\n';  // blank lines keep their numbers
    if (&line == &head) {
      for (std::size_t k = 0; k < kept.size(); ++k)
        out += (k == 0 ? "" : ",") + std::get<1>(kept[k]);
    } else if (!csv_detail::is_blank(line.text)) {
      const std::vector<std::string_view> row = csv_detail::split_fields(line.text);
      require(row.size() == fields.size(), [&] {
        return csv_detail::at(name, line.number) + std::to_string(row.size()) +
               " fields; expected " + std::to_string(fields.size()) + " as in the header";
      });
      for (std::size_t k = 0; k < kept.size(); ++k)
        out.append(k == 0 ? "" : ",").append(row[std::get<2>(kept[k])]);
    }
    out += '\n';
  }
  return out;
}

}  // namespace csympnet
