#include "replay/csv_tokenizer.h"

#include "config/input_file.h"
#include "config/text_escape.h"

#include <algorithm>

namespace lifmcr {
namespace {

constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// Walks the text once, tracking the line and column of the next character.
class CsvScanner {
 public:
  CsvScanner(std::string_view text, const std::string& label, char delimiter,
             const CsvLimits& limits)
      : text_(text), label_(label), delimiter_(delimiter), limits_(limits) {}

  Expected<CsvDocument> Run() {
    CsvDocument document;
    if (text_.substr(0, kUtf8Bom.size()) == kUtf8Bom) {
      document.had_bom = true;
      pos_ = kUtf8Bom.size();
    }
    bool first_line_end = true;
    while (pos_ < text_.size()) {
      CsvRow row;
      row.line = line_;
      if (AtLineEnd()) {
        // An empty line: a row without fields.
        const bool crlf = ConsumeLineEnd();
        if (first_line_end) document.crlf = crlf;
        first_line_end = false;
        document.rows.push_back(std::move(row));
        continue;
      }
      while (true) {
        auto field = ReadField();
        if (!field.ok()) return field.error();
        if (row.fields.size() >= limits_.max_fields_per_row) {
          return MakeError(label_, field->line, field->column,
                           "row has more than " + std::to_string(limits_.max_fields_per_row) +
                               " fields; expected at most that many (is this the right file?)");
        }
        row.fields.push_back(std::move(*field));
        if (pos_ < text_.size() && text_[pos_] == delimiter_) {
          Advance();
          // A delimiter at the very end of a line or the text opens one more empty field.
          if (pos_ >= text_.size() || AtLineEnd()) {
            row.fields.push_back(CsvField{"", line_, column_, false});
          } else {
            continue;
          }
        }
        break;
      }
      if (pos_ < text_.size()) {
        const bool crlf = ConsumeLineEnd();
        if (first_line_end) document.crlf = crlf;
        first_line_end = false;
      }
      document.rows.push_back(std::move(row));
    }
    return document;
  }

 private:
  bool AtLineEnd() const { return text_[pos_] == '\n' || text_[pos_] == '\r'; }

  void Advance() {
    ++pos_;
    ++column_;
  }

  // Consumes "\r\n", "\n" or a lone "\r"; returns whether it was "\r\n".
  bool ConsumeLineEnd() {
    bool crlf = false;
    if (text_[pos_] == '\r') {
      ++pos_;
      if (pos_ < text_.size() && text_[pos_] == '\n') {
        ++pos_;
        crlf = true;
      }
    } else {
      ++pos_;
    }
    ++line_;
    column_ = 1;
    return crlf;
  }

  // Reads one field up to (not including) the next delimiter or line end.
  Expected<CsvField> ReadField() {
    CsvField field{"", line_, column_, false};
    if (pos_ < text_.size() && text_[pos_] == '"') {
      field.quoted = true;
      Advance();
      while (true) {
        if (pos_ >= text_.size()) {
          return MakeError(label_, field.line, field.column,
                           "quoted field never ends: expected a closing '\"' before the end of "
                           "the file");
        }
        const char c = text_[pos_];
        if (c == '"') {
          if (pos_ + 1 < text_.size() && text_[pos_ + 1] == '"') {
            field.text += '"';
            Advance();
            Advance();
            continue;
          }
          Advance();
          break;
        }
        if (field.text.size() >= limits_.max_field_bytes) return FieldTooLong(field);
        if (c == '\n' || c == '\r') {
          // A line break inside quotes belongs to the field, written as '\n'.
          field.text += '\n';
          ConsumeLineEnd();
          continue;
        }
        field.text += c;
        Advance();
      }
      if (pos_ < text_.size() && text_[pos_] != delimiter_ && !AtLineEnd()) {
        return MakeError(label_, line_, column_,
                         std::string("expected '") + delimiter_ +
                             "' or the end of the line after a closing quote, got '" +
                             EscapeText(std::string_view(&text_[pos_], 1)) + "'");
      }
      return field;
    }
    const size_t start = pos_;
    while (pos_ < text_.size() && text_[pos_] != delimiter_ && !AtLineEnd()) Advance();
    if (pos_ - start > limits_.max_field_bytes) return FieldTooLong(field);
    field.text.assign(text_.substr(start, pos_ - start));
    return field;
  }

  Error FieldTooLong(const CsvField& field) const {
    return MakeError(label_, field.line, field.column,
                     "field longer than " + std::to_string(limits_.max_field_bytes) +
                         " bytes; expected short fields (names, numbers)");
  }

  std::string_view text_;
  const std::string& label_;
  char delimiter_;
  CsvLimits limits_;
  size_t pos_ = 0;
  int line_ = 1;
  int column_ = 1;
};

}  // namespace

bool CsvRow::IsBlank() const {
  for (const CsvField& field : fields)
    if (field.quoted || !field.text.empty()) return false;
  return true;
}

size_t CsvRow::WidthWithoutTrailingEmpty() const {
  size_t width = fields.size();
  while (width > 0 && !fields[width - 1].quoted && fields[width - 1].text.empty()) --width;
  return width;
}

Expected<CsvDocument> TokenizeCsv(std::string_view text, const std::string& label, char delimiter,
                                  const CsvLimits& limits) {
  return CsvScanner(text, label, delimiter, limits).Run();
}

char DetectCsvDelimiter(std::string_view text) {
  if (text.substr(0, kUtf8Bom.size()) == kUtf8Bom) text.remove_prefix(kUtf8Bom.size());
  constexpr std::string_view kFrame = "Frame";
  size_t line_start = 0;
  while (line_start < text.size()) {
    const std::string_view rest = text.substr(line_start);
    if (rest.substr(0, kFrame.size()) == kFrame && rest.size() > kFrame.size() &&
        (rest[kFrame.size()] == ',' || rest[kFrame.size()] == ';')) {
      return rest[kFrame.size()];
    }
    // One pass per line (find_first_of calls memchr on its set for every byte).
    const auto end = std::find_if(rest.begin(), rest.end(),
                                  [](char c) { return c == '\r' || c == '\n'; });
    if (end == rest.end()) break;
    line_start += static_cast<size_t>(end - rest.begin()) + 1;
  }
  return ',';
}

std::string FormatCsvField(std::string_view text, char delimiter) {
  const bool needs_quotes =
      text.find_first_of(std::string("\"\r\n") + delimiter) != std::string_view::npos ||
      (!text.empty() && (text.front() == ' ' || text.back() == ' '));
  if (!needs_quotes) return std::string(text);
  std::string quoted = "\"";
  for (const char c : text) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  quoted += '"';
  return quoted;
}

Expected<std::vector<CsvRow>> ReadHeadedCsv(const std::filesystem::path& path,
                                            std::string_view header, std::string_view what,
                                            std::uint64_t max_bytes) {
  // lifmcr's own rows are under a kilobyte; 1 MiB is no real file's line.
  Expected<std::string> text =
      ReadInputText(path, {what, max_bytes, /*allow_fifo=*/false, /*max_line_bytes=*/1u << 20});
  if (!text) return text.error();
  Expected<CsvDocument> doc = TokenizeCsv(*text, path.string());
  if (!doc) return doc.error();
  std::vector<CsvRow> rows;
  bool header_seen = false;
  for (CsvRow& row : doc->rows) {
    if (row.IsBlank()) continue;
    if (!header_seen) {
      std::string joined;
      for (std::size_t k = 0; k < row.fields.size(); ++k)
        joined += (k ? "," : "") + row.fields[k].text;
      if (joined != header)
        return MakeError(path.string(), row.line, 1,
                         "expected the header " + std::string(header));
      header_seen = true;
      continue;
    }
    rows.push_back(std::move(row));
  }
  if (!header_seen)
    return MakeError(path.string(), 1, 1, "no header: expected " + std::string(header));
  return rows;
}

}  // namespace lifmcr
