#include "csv_text.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <system_error>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/io/files.hpp"

namespace csympnet::csv_detail {

namespace {

constexpr std::size_t kQuoteMax = 40;
constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

std::string hex_byte(unsigned char c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02X", static_cast<unsigned>(c));
  return buf;
}

// Every valid file is plain ASCII, so any other byte means a binary or mis-encoded file; it
// is reported at its line rather than as a confusing number-parse error later.
void check_bytes(const std::string& path, std::string_view text) {
  std::size_t line = 1;
  std::size_t col = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n') {
      ++line;
      col = 1;
      continue;
    }
    if (c == '\r' && (i + 1 == text.size() || text[i + 1] != '\n'))
      throw Error(at(path, line) +
                  "carriage return not followed by a newline; expected \\n or \\r\\n line "
                  "endings");
    if (c == 0)
      throw Error(at(path, line) + "NUL byte at character " + std::to_string(col) +
                  "; expected a plain-text CSV file (is this a binary file?)");
    if (c >= 0x80 || (c < 0x20 && c != '\t' && c != '\r'))
      throw Error(at(path, line) + "byte " + hex_byte(c) + " at character " + std::to_string(col) +
                  " is not printable ASCII; expected a plain-text CSV file of numbers");
    ++col;
  }
}

}  // namespace

std::string at(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

std::string quote(std::string_view text) {
  std::string out = "'";
  out += text.substr(0, kQuoteMax);
  if (text.size() > kQuoteMax) out += "...";
  out += "'";
  return out;
}

bool is_blank(std::string_view s) {
  return s.find_first_not_of(" \t") == std::string_view::npos;
}

CsvText load_csv_text(const std::string& path) {
  return csv_text_from_bytes(path, read_text_file(path));
}

CsvText csv_text_from_bytes(const std::string& path, std::string bytes) {
  CsvText f{path, std::make_unique<const std::string>(std::move(bytes)), {}};
  std::string_view text = *f.bytes;
  // Spreadsheet programs often prepend a byte-order mark; it carries no data.
  if (text.substr(0, kUtf8Bom.size()) == kUtf8Bom) text.remove_prefix(kUtf8Bom.size());
  check_bytes(path, text);

  std::size_t number = 1;
  while (!text.empty()) {
    if ((number & 0xFFFF) == 0) throw_if_stop_requested("reading " + path);
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    f.lines.push_back({line, number++});
    if (nl == std::string_view::npos) break;
    text.remove_prefix(nl + 1);
  }
  while (!f.lines.empty() && is_blank(f.lines.back().text)) f.lines.pop_back();
  if (f.lines.empty())
    throw Error(at(path, 1) + "file is empty; expected a header line followed by data rows");
  return f;
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  while (true) {
    const std::size_t comma = line.find(',');
    std::string_view f = line.substr(0, comma);
    const std::size_t b = f.find_first_not_of(" \t");
    f = b == std::string_view::npos ? std::string_view()
                                    : f.substr(b, f.find_last_not_of(" \t") - b + 1);
    fields.push_back(f);
    if (comma == std::string_view::npos) return fields;
    line.remove_prefix(comma + 1);
  }
}

bool parse_finite_double(std::string_view field, double& out, std::string& why) {
  if (field.empty()) {
    why = "an empty field";
    return false;
  }
  std::string_view s = field;
  // from_chars rejects a leading '+', which other tools do write; allow exactly one before a
  // digit or point so "+-1" and "++1" still fail.
  if (s.size() > 1 && s[0] == '+' &&
      (std::isdigit(static_cast<unsigned char>(s[1])) || s[1] == '.'))
    s.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (ec == std::errc::invalid_argument || ptr != s.data() + s.size()) {
    why = quote(field) + ", which is not a number";
    return false;
  }
  if (ec == std::errc::result_out_of_range) {
    why = quote(field) + ", which is outside the range of double (overflow or underflow)";
    return false;
  }
  if (!std::isfinite(out)) {
    why = quote(field) + " (NaN and infinities are not allowed)";
    return false;
  }
  return true;
}

bool parse_integer(std::string_view field, long long& out) {
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), out);
  return !field.empty() && ec == std::errc() && ptr == field.data() + field.size();
}

}  // namespace csympnet::csv_detail
