#pragma once
// A real CSV line splitter (RFC 4180 plus what spreadsheet and Vicon exports
// write): quoted fields with doubled quotes and embedded delimiters or line
// breaks, CRLF, LF or lone CR line endings, an optional UTF-8 byte-order mark,
// and a delimiter chosen by the caller (',' or ';').
//
// Every field keeps where it came from (1-based line and character column,
// counted in bytes after the BOM) so that format readers built on top can say
// "file:line:column: what was expected".

#include "config/error.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr {

struct CsvField {
  std::string text;  // unquoted content (doubled quotes collapsed), not trimmed
  int line = 0;      // line where the field starts
  int column = 0;    // character column where the field starts (its opening quote if quoted)
  bool quoted = false;
};

struct CsvRow {
  int line = 0;                  // line where the row starts
  std::vector<CsvField> fields;  // an empty line has no fields
  // True when the row carries no text: an empty line or only delimiters
  // (",,,,": how a spreadsheet pads a blank line).
  bool IsBlank() const;
  // Number of fields once trailing empty, unquoted fields are ignored.
  size_t WidthWithoutTrailingEmpty() const;
};

struct CsvDocument {
  std::vector<CsvRow> rows;  // one per record, in file order
  bool had_bom = false;      // the text started with the UTF-8 BOM EF BB BF
  bool crlf = false;         // the first line ending was CRLF
};

// Bounds that keep a hostile file from costing memory far beyond its size
// (a 90 MB row of delimiters would otherwise be 90 million field objects).
struct CsvLimits {
  size_t max_fields_per_row = 1 << 20;
  size_t max_field_bytes = 1 << 20;
};

// Splits `text` into rows and fields. `label` (usually the file path) starts
// every error message. Errors: a quoted field that never ends, text between
// a closing quote and the next delimiter, a row or field over `limits`.
Expected<CsvDocument> TokenizeCsv(std::string_view text, const std::string& label,
                                  char delimiter = ',', const CsvLimits& limits = {});

// A comma-separated file of lifmcr's own whose first non-blank row must be
// exactly `header` (e.g. poses_<serial>.csv, aruco_corners.csv): read through
// the safe open (config/input_file.h: a regular file of at most max_bytes),
// tokenized, the header checked (error at its line). Returns the rows after
// the header, blank rows left out.
Expected<std::vector<CsvRow>> ReadHeadedCsv(const std::filesystem::path& path,
                                            std::string_view header, std::string_view what,
                                            std::uint64_t max_bytes);

// The delimiter of a Vicon-style export: the character right after the first
// "Frame" that starts a line (',' or ';'), ',' when there is none.
char DetectCsvDelimiter(std::string_view text);

// `text` as one CSV field: quoted (quotes doubled) only when it contains the
// delimiter, a quote, a line break, or leading/trailing spaces.
std::string FormatCsvField(std::string_view text, char delimiter);

}  // namespace lifmcr
