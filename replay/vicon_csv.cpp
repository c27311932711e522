#include "replay/vicon_csv.h"

#include "config/decimal_number.h"
#include "config/input_file.h"
#include "config/text_escape.h"
#include "replay/csv_tokenizer.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

namespace lifmcr {
namespace {

constexpr double kMissing = std::numeric_limits<double>::quiet_NaN();

// Prefixes Tracker may write before an object name (AG6GR's importer strips
// this one). Only prefixes seen in real exports are listed: anything else
// stays part of the name, so a user sees it rather than a guess.
constexpr std::array<std::string_view, 1> kKnownPrefixes = {"Global Angle "};

constexpr std::array<std::string_view, 6> kSegmentColumns = {"RX", "RY", "RZ", "TX", "TY", "TZ"};
constexpr std::array<std::string_view, 3> kMarkerColumns = {"X", "Y", "Z"};

std::string_view Trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  return text;
}

bool IsSegmentBlockName(std::string_view name) { return name == "Objects" || name == "Segments"; }
bool IsMarkerBlockName(std::string_view name) { return name == "Trajectories"; }

enum class NumberStatus { kOk, kNotANumber, kDecimalComma, kNotFinite };

NumberStatus ParseNumber(std::string_view text, bool allow_decimal_comma, double* value) {
  std::string buffer;
  if (text.find(',') != std::string_view::npos) {
    // Only one comma between digits can be a decimal comma.
    const size_t comma = text.find(',');
    const bool single = text.find(',', comma + 1) == std::string_view::npos;
    if (!single) return NumberStatus::kNotANumber;
    buffer.assign(text);
    buffer[comma] = '.';
    double parsed = 0;
    if (ParseNumber(buffer, false, &parsed) != NumberStatus::kOk) return NumberStatus::kNotANumber;
    if (!allow_decimal_comma) return NumberStatus::kDecimalComma;
    *value = parsed;
    return NumberStatus::kOk;
  }
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty()) return NumberStatus::kNotANumber;
  // from_chars would also take "inf" and "nan"; a Vicon value is digits.
  const char first = text.front();
  if (!(std::isdigit(static_cast<unsigned char>(first)) || first == '-' || first == '.')) {
    return NumberStatus::kNotANumber;
  }
  // A value too small for a double (1e-400) is 0, as strtod rounds it; only
  // one too large is out of range (config/decimal_number.h).
  double parsed = 0;
  const auto [end, error] = FromCharsRounded(text.data(), text.data() + text.size(), parsed);
  if (error == std::errc::result_out_of_range) return NumberStatus::kNotFinite;
  if (error != std::errc() || end != text.data() + text.size()) return NumberStatus::kNotANumber;
  if (!std::isfinite(parsed)) return NumberStatus::kNotFinite;
  *value = parsed;
  return NumberStatus::kOk;
}

template <typename Int>
bool ParseInteger(std::string_view text, Int* value) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty()) return false;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), *value);
  return error == std::errc() && end == text.data() + text.size();
}

// A quote of user text in a message: escaped and at most 40 bytes.
std::string Quote(std::string_view text) { return "'" + Excerpt(text) + "'"; }

// The largest |value| a real capture can write in a column of `unit` (pose
// blocks; kViconCsvLimits), 0 when unchecked.
double MaxAbsValue(std::string_view unit) {
  if (unit == "mm") return kViconCsvLimits.max_abs_position_mm;
  if (unit == "deg") return kViconCsvLimits.max_abs_rotation_deg;
  if (unit == "rad") return kViconCsvLimits.max_abs_rotation_rad;
  return 0.0;
}

std::string FormatNumber(double value) {
  std::array<char, 64> buffer;
  const auto [end, error] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  if (error != std::errc()) return "";
  return std::string(buffer.data(), end);
}

// Parses the blocks of a tokenised file.
class ViconCsvParser {
 public:
  ViconCsvParser(const CsvDocument& document, const std::string& label,
                 const ViconCsvOptions& options)
      : rows_(document.rows), label_(label), options_(options) {}

  Expected<std::vector<ViconBlock>> Run() {
    std::vector<ViconBlock> blocks;
    while (true) {
      while (next_ < rows_.size() && rows_[next_].IsBlank()) ++next_;
      if (next_ >= rows_.size()) break;
      auto block = ParseBlock();
      if (!block.ok()) return block.error();
      // A reader finds a block by its name (ViconCsv::Find): a second block
      // of the same name would go unread, its frames silently dropped.
      for (const ViconBlock& earlier : blocks) {
        if (earlier.name == block->name) {
          return MakeError(label_, block->first_line, 1,
                           "a second block " + Quote(block->name) + " (the first starts at line " +
                               std::to_string(earlier.first_line) +
                               "); expected each block once (was the export pasted twice?)");
        }
      }
      previous_block_ = block->name;
      blocks.push_back(std::move(*block));
    }
    if (blocks.empty()) {
      return MakeError(label_, 0, 0,
                       "no Vicon block: expected a block name (Objects, Segments, Trajectories, "
                       "...) followed by the rate, names, columns and units rows");
    }
    return blocks;
  }

 private:
  Error ErrorAt(const CsvField& field, const std::string& what) const {
    return MakeError(label_, field.line, field.column, what);
  }
  Error ErrorAt(const CsvRow& row, const std::string& what) const {
    return MakeError(label_, row.line, row.fields.empty() ? 0 : 1, what);
  }

  // The line after the last row, for "ends early" errors.
  int EndLine() const { return rows_.empty() ? 1 : rows_.back().line + 1; }

  // Next header row of the block; an empty line or the end of the file is an error.
  Expected<const CsvRow*> HeaderRow(const ViconBlock& block, const char* expected) {
    if (next_ >= rows_.size()) {
      return MakeError(label_, EndLine(), 0,
                       "the file ends inside the header of block " + Quote(block.name) + " (line " +
                           std::to_string(block.first_line) + "): expected " + expected);
    }
    const CsvRow& row = rows_[next_++];
    if (row.fields.empty()) {
      return MakeError(
          label_, row.line, 0,
          "empty line inside the header of block " + Quote(block.name) + ": expected " + expected);
    }
    return &row;
  }

  std::string DescribeField(const ViconBlock& block, size_t field_index) const {
    std::string text = "field " + std::to_string(field_index + 1);
    if (field_index == 0) return text + " (Frame)";
    if (field_index == 1) return text + " (Sub Frame)";
    const size_t column = field_index - 2;
    if (column < block.columns.size()) {
      const ViconColumn& c = block.columns[column];
      text += " (" + (c.subject.empty() ? std::string() : Excerpt(c.subject) + " ") +
              Excerpt(c.name) + ")";
    }
    return text;
  }

  // Data rows after a blank line inside a block read as a new block.
  std::string AfterBlankLineHint() const {
    if (previous_block_.empty()) return "";
    return " (a blank line ended block " + Quote(previous_block_) +
           " above, so a new block must start here)";
  }

  Status ParseNameRow(const CsvRow& row, ViconBlock* block) {
    if (row.fields.size() != 1 && row.WidthWithoutTrailingEmpty() != 1) {
      const size_t width = row.WidthWithoutTrailingEmpty();
      if (width == 0) return ErrorAt(row, "expected a block name, got an empty field");
      return ErrorAt(row.fields[1],
                     "expected only a block name (Objects, Segments, Trajectories, ...) on the "
                     "first line of a block, got " +
                         std::to_string(row.fields.size()) + " fields" + AfterBlankLineHint());
    }
    const std::string_view name = Trim(row.fields[0].text);
    double number = 0;
    if (name.empty() || ParseNumber(name, true, &number) == NumberStatus::kOk) {
      return ErrorAt(row.fields[0],
                     "expected a block name (Objects, Segments, Trajectories, "
                     "...), got " +
                         Quote(name) + AfterBlankLineHint());
    }
    block->name = std::string(name);
    block->first_line = row.line;
    return Status::Ok();
  }

  Status ParseRateRow(const CsvRow& row, ViconBlock* block) {
    const size_t width = row.WidthWithoutTrailingEmpty();
    if (width != 1) {
      return ErrorAt(width == 0 ? row.fields[0] : row.fields[width - 1],
                     "expected the frame rate of block " + Quote(block->name) +
                         " (one number, Hz) on the line after its name, got " +
                         std::to_string(width) + " fields");
    }
    const std::string_view text = Trim(row.fields[0].text);
    double rate = 0;
    if (ParseNumber(text, false, &rate) != NumberStatus::kOk || rate < 1 ||
        rate != std::floor(rate) || rate > kViconCsvLimits.max_rate_hz) {
      return ErrorAt(row.fields[0], "expected the frame rate of block " + Quote(block->name) +
                                        " (a whole number of Hz, 1 .. " +
                                        std::to_string(kViconCsvLimits.max_rate_hz) + "), got " +
                                        Quote(text));
    }
    block->rate_hz = static_cast<int>(rate);
    return Status::Ok();
  }

  Status ParseColumnsRow(const CsvRow& row, ViconBlock* block) {
    const size_t width = row.WidthWithoutTrailingEmpty();
    if (width < 1 || Trim(row.fields[0].text) != "Frame") {
      return ErrorAt(row.fields[0], "expected 'Frame' in the columns row of block " +
                                        Quote(block->name) + ", got " +
                                        Quote(Trim(row.fields[0].text)));
    }
    if (width < 2 || Trim(row.fields[1].text) != "Sub Frame") {
      const CsvField& field = width < 2 ? row.fields[0] : row.fields[1];
      return ErrorAt(field, "expected 'Sub Frame' after 'Frame' in the columns row of block " +
                                Quote(block->name));
    }
    if (width < 3) {
      return ErrorAt(row.fields[1], "block " + Quote(block->name) +
                                        " has no data columns after 'Frame,Sub Frame'");
    }
    if (width - 2 > kViconCsvLimits.max_columns) {
      return ErrorAt(row.fields[kViconCsvLimits.max_columns + 2],
                     "block " + Quote(block->name) + " has " + std::to_string(width - 2) +
                         " data columns, expected at most " +
                         std::to_string(kViconCsvLimits.max_columns) +
                         " (more objects or markers than a Vicon system tracks)");
    }
    for (size_t i = 2; i < width; ++i) {
      const std::string_view name = Trim(row.fields[i].text);
      if (name.empty()) {
        return ErrorAt(row.fields[i], "field " + std::to_string(i + 1) +
                                          ": expected a column name (RX, TX, X, ...), got an "
                                          "empty field");
      }
      block->columns.push_back(ViconColumn{"", "", std::string(name), ""});
    }
    return Status::Ok();
  }

  Status ParseSubjectsRow(const CsvRow& row, ViconBlock* block) {
    const size_t width = row.WidthWithoutTrailingEmpty();
    const size_t full_width = block->columns.size() + 2;
    if (width > full_width) {
      return ErrorAt(row.fields[width - 1], "the names row has " + std::to_string(width) +
                                                " fields but the columns row below it only " +
                                                std::to_string(full_width));
    }
    for (size_t i = 0; i < 2 && i < width; ++i) {
      if (!Trim(row.fields[i].text).empty()) {
        return ErrorAt(row.fields[i], "field " + std::to_string(i + 1) +
                                          " of the names row must be empty (it sits above " +
                                          (i == 0 ? "Frame" : "Sub Frame") + "), got " +
                                          Quote(row.fields[i].text));
      }
    }
    std::string subject;
    std::string prefix;
    for (size_t c = 0; c < block->columns.size(); ++c) {
      const size_t i = c + 2;
      if (i < width && !Trim(row.fields[i].text).empty()) {
        std::string_view name = Trim(row.fields[i].text);
        prefix.clear();
        for (const std::string_view known : kKnownPrefixes) {
          if (name.substr(0, known.size()) == known && name.size() > known.size()) {
            prefix = std::string(known);
            name.remove_prefix(known.size());
          }
        }
        subject = std::string(name);
      }
      block->columns[c].subject = subject;
      block->columns[c].prefix = prefix;
    }
    std::unordered_set<std::string> seen;
    for (const ViconColumn& column : block->columns) {
      std::string subject_name(SubjectOf(column.subject));
      if (!column.subject.empty() && seen.insert(subject_name).second) {
        block->subjects.push_back(std::move(subject_name));
      }
    }
    return Status::Ok();
  }

  Status ParseUnitsRow(const CsvRow& row, ViconBlock* block) {
    const size_t width = row.WidthWithoutTrailingEmpty();
    const size_t full_width = block->columns.size() + 2;
    if (width > full_width) {
      return ErrorAt(row.fields[width - 1], "the units row has " + std::to_string(width) +
                                                " fields but the columns row above it only " +
                                                std::to_string(full_width));
    }
    for (size_t c = 0; c < block->columns.size(); ++c) {
      const size_t i = c + 2;
      if (i < width) block->columns[c].unit = std::string(Trim(row.fields[i].text));
    }
    return Status::Ok();
  }

  // Groups of a pose block, checked: [first column, end) per entity.
  Status CheckPoseGroups(const CsvRow& names_row, const CsvRow& columns_row,
                         const CsvRow& units_row, ViconBlock* block) {
    const bool segments = IsSegmentBlockName(block->name);
    const std::vector<std::string_view> expected(
        segments ? kSegmentColumns.begin() : kMarkerColumns.begin(),
        segments ? kSegmentColumns.end() : kMarkerColumns.end());
    const std::string expected_text = segments ? "RX, RY, RZ, TX, TY, TZ" : "X, Y, Z";
    std::unordered_set<std::string> seen_entities;
    size_t begin = 0;
    while (begin < block->columns.size()) {
      const ViconColumn& first = block->columns[begin];
      if (first.subject.empty()) {
        return ErrorAt(names_row.fields.size() > begin + 2 ? names_row.fields[begin + 2]
                                                           : names_row.fields.back(),
                       "column " + std::to_string(begin + 3) + " (" + first.name + ") of block " +
                           Quote(block->name) + " has no subject name above it in the names row");
      }
      size_t end = begin + 1;
      while (end < block->columns.size() && block->columns[end].subject == first.subject &&
             !(names_row.fields.size() > end + 2 && !Trim(names_row.fields[end + 2].text).empty()))
        ++end;
      const std::string full_name = first.prefix + first.subject;
      if (!seen_entities.insert(full_name).second) {
        return ErrorAt(names_row.fields[begin + 2],
                       "block " + Quote(block->name) + " names " + Quote(full_name) +
                           " twice: each object, segment or marker needs its own name");
      }
      std::vector<std::string_view> names;
      for (size_t c = begin; c < end; ++c) names.push_back(block->columns[c].name);
      for (const std::string_view name : expected) {
        if (std::count(names.begin(), names.end(), name) != 1) {
          const bool missing = std::count(names.begin(), names.end(), name) == 0;
          return ErrorAt(columns_row.fields[begin + 2],
                         Quote(first.subject) + " in block " + Quote(block->name) + " " +
                             (missing ? "has no " : "has more than one ") + std::string(name) +
                             " column (fields " + std::to_string(begin + 3) + ".." +
                             std::to_string(end + 2) + "): expected exactly " + expected_text);
        }
      }
      if (names.size() != expected.size()) {
        return ErrorAt(columns_row.fields[begin + 2],
                       Quote(first.subject) + " in block " + Quote(block->name) + " has " +
                           std::to_string(names.size()) + " columns (fields " +
                           std::to_string(begin + 3) + ".." + std::to_string(end + 2) +
                           "): expected exactly " + expected_text);
      }
      std::string rotation_unit;
      for (size_t c = begin; c < end; ++c) {
        const ViconColumn& column = block->columns[c];
        const bool is_rotation = column.name.front() == 'R';
        const bool known =
            is_rotation ? (column.unit == "deg" || column.unit == "rad") : column.unit == "mm";
        const CsvField& unit_field =
            units_row.fields.size() > c + 2 ? units_row.fields[c + 2] : units_row.fields.back();
        if (!known) {
          return ErrorAt(unit_field, "field " + std::to_string(c + 3) + " (" +
                                         Excerpt(column.subject) + " " + column.name +
                                         "): unknown unit " +
                                         Quote(column.unit) + ", expected " +
                                         (is_rotation ? "'deg' or 'rad'" : "'mm'"));
        }
        if (is_rotation) {
          if (!rotation_unit.empty() && rotation_unit != column.unit) {
            return ErrorAt(unit_field, "field " + std::to_string(c + 3) + " (" +
                                           Excerpt(column.subject) + " " + column.name +
                                           "): unit " + Quote(column.unit) +
                                           " differs from " + Quote(rotation_unit) +
                                           " of the other rotation columns of the group");
          }
          rotation_unit = column.unit;
        }
        column_max_abs_[c] = MaxAbsValue(column.unit);
      }
      groups_.push_back({begin, end});
      begin = end;
    }
    return Status::Ok();
  }

  Expected<ViconBlock> ParseBlock() {
    ViconBlock block;
    groups_.clear();
    column_max_abs_.clear();
    if (Status s = ParseNameRow(rows_[next_++], &block); !s.ok()) return s.error();
    auto rate_row = HeaderRow(block, "the frame rate (Hz)");
    if (!rate_row.ok()) return rate_row.error();
    if (Status s = ParseRateRow(**rate_row, &block); !s.ok()) return s.error();
    auto names_row = HeaderRow(block, "the names row (,,Subject:Name,...)");
    if (!names_row.ok()) return names_row.error();
    auto columns_row = HeaderRow(block, "the columns row (Frame,Sub Frame,...)");
    if (!columns_row.ok()) return columns_row.error();
    if (Status s = ParseColumnsRow(**columns_row, &block); !s.ok()) return s.error();
    if (Status s = ParseSubjectsRow(**names_row, &block); !s.ok()) return s.error();
    auto units_row = HeaderRow(block, "the units row (,,mm,...)");
    if (!units_row.ok()) return units_row.error();
    if (Status s = ParseUnitsRow(**units_row, &block); !s.ok()) return s.error();
    column_max_abs_.assign(block.columns.size(), 0.0);
    if (block.IsPoseBlock()) {
      if (Status s = CheckPoseGroups(**names_row, **columns_row, **units_row, &block); !s.ok())
        return s.error();
    }
    const size_t first_data = next_;
    while (next_ < rows_.size() && !rows_[next_].IsBlank()) {
      if (Status s = ParseDataRow(rows_[next_], &block); !s.ok()) return s.error();
      ++next_;
    }
    if (next_ == first_data) {
      return MakeError(label_, next_ < rows_.size() ? rows_[next_].line : EndLine(), 0,
                       "block " + Quote(block.name) + " (line " + std::to_string(block.first_line) +
                           ") has a header but no data rows: expected 'frame,sub frame,values'");
    }
    return block;
  }

  Status ParseDataRow(const CsvRow& row, ViconBlock* block) {
    const size_t full_width = block->columns.size() + 2;
    const size_t width = row.fields.size();
    bool all_missing = false;
    if (width < full_width) {
      if (!options_.short_rows_are_missing || width < 2) {
        return ErrorAt(row.fields.back(),
                       "line " + std::to_string(row.line) + " has " + std::to_string(width) +
                           " fields, expected " + std::to_string(full_width) + " (block " +
                           Quote(block->name) + "; " +
                           (width < 2 ? "a row needs at least frame and sub frame"
                                      : "is the file cut short?") +
                           ")");
      }
      all_missing = true;
    } else if (width > full_width && row.WidthWithoutTrailingEmpty() > full_width) {
      return ErrorAt(row.fields[full_width], "line " + std::to_string(row.line) + " has " +
                                                 std::to_string(row.WidthWithoutTrailingEmpty()) +
                                                 " fields, expected " + std::to_string(full_width) +
                                                 " (block " + Quote(block->name) + ")");
    }
    int64_t frame = 0;
    if (!ParseInteger(Trim(row.fields[0].text), &frame) || frame < 0 ||
        frame > kViconCsvLimits.max_frame) {
      return ErrorAt(row.fields[0], "field 1 (Frame): expected an integer frame number 0 .. " +
                                        std::to_string(kViconCsvLimits.max_frame) + ", got " +
                                        Quote(row.fields[0].text));
    }
    int sub_frame = 0;
    if (!ParseInteger(Trim(row.fields[1].text), &sub_frame) || sub_frame < 0 ||
        sub_frame > kViconCsvLimits.max_sub_frame) {
      return ErrorAt(row.fields[1], "field 2 (Sub Frame): expected an integer 0 .. " +
                                        std::to_string(kViconCsvLimits.max_sub_frame) + ", got " +
                                        Quote(row.fields[1].text));
    }
    if (!block->frames.empty()) {
      const int64_t last_frame = block->frames.back();
      const int last_sub_frame = block->sub_frames.back();
      if (frame < last_frame || (frame == last_frame && sub_frame <= last_sub_frame)) {
        return ErrorAt(row.fields[0], "frame " + std::to_string(frame) + " sub frame " +
                                          std::to_string(sub_frame) + " follows frame " +
                                          std::to_string(last_frame) + " sub frame " +
                                          std::to_string(last_sub_frame) + " (line " +
                                          std::to_string(block->row_lines.back()) +
                                          "): frame numbers must increase");
      }
    }
    const size_t row_index = block->frames.size();
    block->frames.push_back(frame);
    block->sub_frames.push_back(sub_frame);
    block->row_lines.push_back(row.line);
    for (size_t c = 0; c < block->columns.size(); ++c) {
      const size_t i = c + 2;
      if (all_missing || i >= width) {
        block->values.push_back(kMissing);
        block->cell_columns.push_back(0);
        continue;
      }
      const CsvField& field = row.fields[i];
      block->cell_columns.push_back(field.column);
      const std::string_view text = Trim(field.text);
      if (text.empty()) {
        block->values.push_back(kMissing);
        continue;
      }
      double value = 0;
      switch (ParseNumber(text, options_.allow_decimal_comma, &value)) {
        case NumberStatus::kOk:
          if (column_max_abs_[c] > 0 && std::abs(value) > column_max_abs_[c]) {
            return ErrorAt(field, DescribeField(*block, i) + ": " + Quote(text) + " " +
                                      block->columns[c].unit + " is outside +-" +
                                      FormatNumber(column_max_abs_[c]) + " " +
                                      block->columns[c].unit +
                                      " (what a real capture volume or rotation can hold)");
          }
          block->values.push_back(value);
          break;
        case NumberStatus::kDecimalComma:
          return ErrorAt(field, DescribeField(*block, i) + ": " + Quote(text) +
                                    " has a decimal comma (Tracker's 'Local Numeric Format'); "
                                    "expected a '.' decimal point, or allow decimal commas "
                                    "explicitly");
        case NumberStatus::kNotFinite:
          return ErrorAt(field, DescribeField(*block, i) + ": " + Quote(text) +
                                    " is larger than a double can hold (about 1.8e308); "
                                    "expected a finite number");
        case NumberStatus::kNotANumber:
          return ErrorAt(field,
                         DescribeField(*block, i) + ": expected a number, got " + Quote(text));
      }
    }
    // A group is one object, segment or marker: all of it or none of it.
    for (const auto& [begin, end] : groups_) {
      size_t present = 0;
      for (size_t c = begin; c < end; ++c)
        if (!std::isnan(block->at(row_index, c))) ++present;
      if (present == 0 || present == end - begin) continue;
      std::string have;
      std::string lack;
      size_t first_empty = end;
      for (size_t c = begin; c < end; ++c) {
        const bool is_present = !std::isnan(block->at(row_index, c));
        std::string& list = is_present ? have : lack;
        if (!list.empty()) list += ",";
        list += block->columns[c].name;
        if (!is_present && first_empty == end) first_empty = c;
      }
      return ErrorAt(row.fields[first_empty + 2],
                     "partial tuple for " + Quote(block->columns[begin].subject) + " at frame " +
                         std::to_string(frame) + ": " + have + " present but " + lack +
                         " empty; a group is either all present or all empty (untracked)");
    }
    return Status::Ok();
  }

  const std::vector<CsvRow>& rows_;
  const std::string& label_;
  const ViconCsvOptions& options_;
  size_t next_ = 0;
  std::string previous_block_;                     // name of the last complete block
  std::vector<std::pair<size_t, size_t>> groups_;  // of the block being parsed
  std::vector<double> column_max_abs_;             // per column of the block, 0: unchecked
};

}  // namespace

std::string_view SubjectOf(std::string_view full_name) {
  return full_name.substr(0, full_name.find(':'));
}

int ViconBlock::ColumnOf(size_t row, size_t column) const {
  const size_t index = row * columns.size() + column;
  return index < cell_columns.size() ? cell_columns[index] : 0;
}

std::vector<std::string> ViconBlock::Entities() const {
  std::vector<std::string> entities;
  std::unordered_set<std::string_view> seen;
  for (const ViconColumn& column : columns) {
    if (column.subject.empty()) continue;
    if (seen.insert(column.subject).second) entities.push_back(column.subject);
  }
  return entities;
}

std::optional<size_t> ViconBlock::FindColumn(std::string_view full_name,
                                             std::string_view name) const {
  for (size_t c = 0; c < columns.size(); ++c)
    if (columns[c].subject == full_name && columns[c].name == name) return c;
  return std::nullopt;
}

bool ViconBlock::IsPoseBlock() const { return IsSegmentBlockName(name) || IsMarkerBlockName(name); }

const ViconBlock* ViconCsv::Find(std::string_view name) const {
  for (const ViconBlock& block : blocks)
    if (block.name == name) return &block;
  return nullptr;
}

std::vector<std::string> ViconCsv::BlockNames() const {
  std::vector<std::string> names;
  for (const ViconBlock& block : blocks) names.push_back(block.name);
  return names;
}

Expected<ViconCsv> ParseViconCsv(std::string_view text, const std::string& label,
                                 const ViconCsvOptions& options) {
  if (Status s = CheckTextEncoding(text, label, "a Vicon CSV export"); !s) return s.error();
  const char delimiter = DetectCsvDelimiter(text);
  CsvLimits limits;
  // Trailing padding may widen a row past the data columns.
  limits.max_fields_per_row = kViconCsvLimits.max_columns + 64;
  limits.max_field_bytes = kViconCsvLimits.max_field_bytes;
  auto document = TokenizeCsv(text, label, delimiter, limits);
  if (!document.ok()) return document.error();
  auto blocks = ViconCsvParser(*document, label, options).Run();
  if (!blocks.ok()) return blocks.error();
  ViconCsv csv;
  csv.path = label;
  csv.blocks = std::move(*blocks);
  csv.delimiter = delimiter;
  csv.crlf = document->crlf;
  return csv;
}

Expected<ViconCsv> ReadViconCsv(const std::filesystem::path& path, const ViconCsvOptions& options) {
  Expected<std::string> text =
      ReadInputText(path, {"a Vicon CSV export", kViconCsvLimits.max_file_bytes,
                           /*allow_fifo=*/false, kViconCsvLimits.max_line_bytes});
  if (!text) return text.error();
  return ParseViconCsv(*text, EscapeText(path.string()), options);
}

std::string FormatViconCsv(const ViconCsv& csv) {
  const std::string end_of_line = csv.crlf ? "\r\n" : "\n";
  const char d = csv.delimiter;
  std::string text;
  for (size_t b = 0; b < csv.blocks.size(); ++b) {
    const ViconBlock& block = csv.blocks[b];
    if (b > 0) text += end_of_line;
    text += FormatCsvField(block.name, d) + end_of_line;
    text += std::to_string(block.rate_hz) + end_of_line;
    std::string names{d, d};
    std::string columns = "Frame" + std::string(1, d) + "Sub Frame";
    std::string units{d, d};
    for (size_t c = 0; c < block.columns.size(); ++c) {
      const ViconColumn& column = block.columns[c];
      const bool starts_group = c == 0 || column.subject != block.columns[c - 1].subject ||
                                column.prefix != block.columns[c - 1].prefix;
      if (c > 0) {
        names += d;
        units += d;
      }
      if (starts_group) names += FormatCsvField(column.prefix + column.subject, d);
      columns += d + FormatCsvField(column.name, d);
      units += FormatCsvField(column.unit, d);
    }
    text += names + end_of_line + columns + end_of_line + units + end_of_line;
    for (size_t r = 0; r < block.num_rows(); ++r) {
      text += std::to_string(block.frames[r]) + d +
              std::to_string(r < block.sub_frames.size() ? block.sub_frames[r] : 0);
      for (size_t c = 0; c < block.columns.size(); ++c) {
        text += d;
        const double value = block.at(r, c);
        if (!std::isnan(value)) text += FormatNumber(value);
      }
      text += end_of_line;
    }
  }
  return text;
}

Status WriteViconCsv(const std::filesystem::path& path, const ViconCsv& csv) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return MakeError(path.string(), 0, 0, "cannot open for writing");
  const std::string text = FormatViconCsv(csv);
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) return MakeError(path.string(), 0, 0, "write failed");
  return Status::Ok();
}

ViconBlockSummary Summarize(const ViconBlock& block) {
  ViconBlockSummary summary;
  summary.name = block.name;
  summary.rate_hz = block.rate_hz;
  summary.subjects = block.subjects;
  summary.num_entities = block.Entities().size();
  std::unordered_set<std::string_view> units;
  for (const ViconColumn& column : block.columns) {
    if (units.insert(column.unit).second) summary.units.push_back(column.unit);
  }
  summary.num_frames = block.num_rows();
  if (!block.frames.empty()) {
    summary.first_frame = block.frames.front();
    summary.last_frame = block.frames.back();
  }
  summary.frames_with_missing.assign(block.subjects.size(), 0);
  // One pass over the values: the subject of each column, then per row the
  // subjects with a missing value (counted once per row).
  std::unordered_map<std::string_view, size_t> subject_index;
  for (size_t s = 0; s < block.subjects.size(); ++s) subject_index.emplace(block.subjects[s], s);
  std::vector<size_t> subject_of_column(block.num_columns(), block.subjects.size());
  for (size_t c = 0; c < block.num_columns(); ++c) {
    const auto it = subject_index.find(SubjectOf(block.columns[c].subject));
    if (!block.columns[c].subject.empty() && it != subject_index.end())
      subject_of_column[c] = it->second;
  }
  std::vector<size_t> counted_row(block.subjects.size(), block.num_rows());
  for (size_t r = 0; r < block.num_rows(); ++r) {
    for (size_t c = 0; c < block.num_columns(); ++c) {
      const size_t s = subject_of_column[c];
      if (s < block.subjects.size() && counted_row[s] != r && std::isnan(block.at(r, c))) {
        counted_row[s] = r;
        ++summary.frames_with_missing[s];
      }
    }
  }
  return summary;
}

std::vector<ViconBlockSummary> Summarize(const ViconCsv& csv) {
  std::vector<ViconBlockSummary> summaries;
  for (const ViconBlock& block : csv.blocks) summaries.push_back(Summarize(block));
  return summaries;
}

std::string ViconBlockSummary::OneLine() const {
  std::string line =
      name + ": " + std::to_string(rate_hz) + " Hz, " + std::to_string(num_frames) + " frames";
  if (num_frames > 0) line += " " + std::to_string(first_frame) + ".." + std::to_string(last_frame);
  line += ", " + std::to_string(num_entities) + " entities";
  if (!subjects.empty()) {
    line += ", subjects ";
    for (size_t s = 0; s < subjects.size(); ++s) {
      if (s > 0) line += ", ";
      line += subjects[s] + " (" + std::to_string(frames_with_missing[s]) +
              " frames with missing data)";
    }
  }
  std::string unit_list;
  for (const std::string& unit : units) unit_list += (unit_list.empty() ? "" : ",") + unit;
  line += ", units " + (unit_list.empty() ? std::string("none") : unit_list);
  return line;
}

}  // namespace lifmcr
