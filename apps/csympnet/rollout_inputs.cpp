#include "rollout_inputs.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/io/files.hpp"

namespace csympnet::cli {

namespace {

std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  for (char c : line) {
    if (c == ',') {
      out.push_back(field);
      field.clear();
    } else if (c != ' ' && c != '\t') {
      field += c;
    }
  }
  out.push_back(field);
  return out;
}

// A finite number filling the whole field, or Error naming where.
double field_number(const std::string& field, const std::string& where) {
  if (field.empty()) throw Error(where + ": an empty field; expected a number");
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(field.c_str(), &end);
  if (end != field.c_str() + field.size() || errno == ERANGE || !std::isfinite(v))
    throw Error(where + ": '" + field + "' is not a finite number; expected a number");
  return v;
}

}  // namespace

Matrix read_rollout_inputs(const std::string& path, Index m, long steps, double t0, double h) {
  const std::string text = read_text_file(path);
  std::vector<std::string> lines;
  std::string line;
  for (char c : text) {
    if (c == '\n') {
      lines.push_back(line);
      line.clear();
    } else if (c != '\r') {
      line += c;
    }
  }
  if (!line.empty()) lines.push_back(line);
  while (!lines.empty() && lines.back().find_first_not_of(" \t") == std::string::npos)
    lines.pop_back();
  std::string expected_header;
  for (Index j = 1; j <= m; ++j) expected_header += (j > 1 ? "," : "") + ("u" + std::to_string(j));
  if (lines.empty())
    throw Error(path + ": empty; expected a header '[t,]" + expected_header +
                "' and a row of inputs per sample time of the rollout");
  const std::vector<std::string> header = split_fields(lines.front());
  const bool has_t = !header.empty() && header.front() == "t";
  bool header_ok = static_cast<Index>(header.size()) == m + (has_t ? 1 : 0);
  for (Index j = 0; header_ok && j < m; ++j)
    header_ok =
        header[static_cast<std::size_t>(j + (has_t ? 1 : 0))] == "u" + std::to_string(j + 1);
  if (!header_ok)
    throw Error(path + ":1: header '" + lines.front() + "'; expected '[t,]" + expected_header +
                "' (the model reads " + std::to_string(m) + " input(s))");
  const long rows = static_cast<long>(lines.size()) - 1;
  if (rows != steps + 1)
    throw Error(path + ": " + std::to_string(rows) + " rows of inputs; expected " +
                std::to_string(steps + 1) +
                ", one per sample time of the rollout (t0 and each of the " +
                std::to_string(steps) + " steps of --steps)");
  Matrix u(m, steps + 1);
  for (long k = 0; k <= steps; ++k) {
    const std::string where = path + ":" + std::to_string(k + 2);
    const std::vector<std::string> f = split_fields(lines[static_cast<std::size_t>(k + 1)]);
    if (f.size() != header.size())
      throw Error(where + ": " + std::to_string(f.size()) + " fields; expected " +
                  std::to_string(header.size()) + " as in the header");
    if (has_t) {
      const double t = field_number(f.front(), where);
      const double want = t0 + static_cast<double>(k) * h;
      if (!(std::abs(t - want) <= 1e-9 * std::max(h, std::abs(want))))
        throw Error(where + ": t = " + f.front() + "; expected the rollout's sample time " +
                    number_text(want) + " (t0 + " + std::to_string(k) + " steps of --h " +
                    number_text(h) + ")");
    }
    for (Index j = 0; j < m; ++j)
      u(j, k) = field_number(f[static_cast<std::size_t>(j + (has_t ? 1 : 0))], where);
  }
  return u;
}

}  // namespace csympnet::cli
