// Internal to csv.cpp: strict line and field scanning for the CSV readers.
//
// Kept apart from the format logic so the byte-level rules (ASCII only, CRLF, trailing blank
// lines, number syntax) live in one place.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace csympnet::csv_detail {

struct Line {
  std::string_view text;  // without the line ending
  std::size_t number;     // 1-based
};

// A CSV file's text split into lines. Trailing blank lines are dropped, so `lines` ends at
// the last non-blank line. The bytes live on the heap so the line views stay valid when a
// CsvText is moved (a moved short std::string would take its inline buffer with it).
struct CsvText {
  std::string path;
  std::unique_ptr<const std::string> bytes;
  std::vector<Line> lines;
};
// Throws Error for unreadable, empty or non-text files.
CsvText load_csv_text(const std::string& path);
// The same checks on text already in memory; `path` only names it in messages.
CsvText csv_text_from_bytes(const std::string& path, std::string bytes);

// "path:line: " — every reader message starts like this.
std::string at(const std::string& path, std::size_t line);

// Shows user text in a message: quoted, cut to a readable length.
std::string quote(std::string_view text);

bool is_blank(std::string_view s);

// Splits on ',' and trims spaces and tabs around each field.
std::vector<std::string_view> split_fields(std::string_view line);

// Parses a whole field as a finite double (locale-independent). On failure returns false and
// sets `why` to what was wrong, phrased to follow "expected a finite number, got ...".
bool parse_finite_double(std::string_view field, double& out, std::string& why);

// Parses a whole field as a (possibly negative) decimal integer.
bool parse_integer(std::string_view field, long long& out);

}  // namespace csympnet::csv_detail
