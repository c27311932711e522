#pragma once
// Vicon CSV exports (Nexus and Tracker): the block model, a strict reader and
// a writer, for the exports of the LiFMCR dataset.
//
// A file is a list of blocks separated by blank lines. Each block is
//   L1  <block name>            Objects (Tracker), Segments, Trajectories, Joints, ...
//   L2  <rate>                  Hz
//   L3  ,,<Subject:Name>,,,...  a name at the first column of its group of columns
//   L4  Frame,Sub Frame,<col>,  RX,RY,RZ,TX,TY,TZ per object/segment; X,Y,Z per marker
//   L5  ,,<unit>,...            mm, deg, rad
//   L6+ <frame>,<sub frame>,<value>,...
//
// Rules (strict but realistic):
// * Header rows (L1..L5) may carry trailing delimiters (spreadsheets pad
//   them); they are ignored there. Data rows must have the full width
//   2 + columns; empty fields after the full width are tolerated (a
//   spreadsheet pads every line of a file to its widest block).
// * An empty cell is missing data (NaN here, never 0). In the pose blocks
//   (Objects, Segments: groups RX..TZ; Trajectories: groups X,Y,Z) a group is
//   either all present or all empty; a partial group is an error.
// * Pose blocks must use known units: mm for T*, X, Y, Z; deg or rad (the
//   same for RX, RY, RZ of a group) for R*. Other blocks (Devices, Model
//   Outputs, Joints, ...) keep their units as written, unchecked.
// * Frame numbers are integers; (frame, sub frame) strictly increase.
// * Each block name appears once (blocks are found by name).
// * Values are decimal numbers; one too small for a double (1e-400) reads as
//   0, one too large (1e400) is an error (config/decimal_number.h).
// * The delimiter is ',' or ';' (detected from the "Frame" row); a decimal
//   comma ("0,5" in a ';' file, Tracker's "Local Numeric Format") is refused
//   unless ViconCsvOptions::allow_decimal_comma is set.
// Every error names the file, the line and the character column, and the
// field number with the column it belongs to.

#include "config/error.h"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr {

struct ViconColumn {
  std::string subject;  // "cam0:cam0", "boite:gauche_ext" as written, without the prefix
  std::string prefix;   // a recognised prefix before the subject ("Global Angle "), else empty
  std::string name;     // RX, RY, RZ, TX, TY, TZ, X, Y, Z (as written in L4)
  std::string unit;     // as written in L5: mm, deg, rad in the pose blocks
};

// The part of "Subject:Segment" before the first ':' (all of it without one).
std::string_view SubjectOf(std::string_view full_name);

struct ViconBlock {
  std::string name;                   // Objects, Segments, Trajectories, ...
  int rate_hz = 0;                    // L2
  int first_line = 0;                 // line of L1 in the file (0 when built in memory)
  std::vector<std::string> subjects;  // distinct SubjectOf(column.subject), in column order
  std::vector<ViconColumn> columns;   // the data columns after Frame and Sub Frame
  std::vector<int64_t> frames;        // one per data row
  std::vector<int> sub_frames;        // one per data row
  std::vector<double> values;         // row-major rows x columns; NaN = empty cell = missing
  // Where each value came from, for errors found after parsing; empty when
  // the block was built in memory.
  std::vector<int> row_lines;     // one per data row
  std::vector<int> cell_columns;  // row-major like values: character column of the field

  size_t num_rows() const { return frames.size(); }
  size_t num_columns() const { return columns.size(); }
  double at(size_t row, size_t column) const { return values[row * columns.size() + column]; }
  int LineOf(size_t row) const { return row < row_lines.size() ? row_lines[row] : 0; }
  int ColumnOf(size_t row, size_t column) const;
  // Distinct full names ("cam0:cam0", markers, segments) in column order.
  std::vector<std::string> Entities() const;
  // Index of the column `name` of entity `full_name`, if there is one.
  std::optional<size_t> FindColumn(std::string_view full_name, std::string_view name) const;
  // True for Objects and Segments (RX..TZ groups) and Trajectories (X,Y,Z groups).
  bool IsPoseBlock() const;
};

struct ViconCsv {
  std::string path;                // the file it was read from, for messages
  std::vector<ViconBlock> blocks;  // in file order
  char delimiter = ',';
  bool crlf = false;  // line endings of the file (the writer uses them too)

  // The first block called `name`, or nullptr.
  const ViconBlock* Find(std::string_view name) const;
  std::vector<std::string> BlockNames() const;
};

// What a real Vicon export can hold (README, "Limits of every input");
// anything beyond is refused before it costs time or memory.
struct ViconCsvLimits {
  std::uint64_t max_file_bytes = 128u << 20;  // ~2 h of a 3-object Tracker export at 80 Hz
  size_t max_columns = 60000;                 // data columns of a block: 10000 objects x 6
  size_t max_field_bytes = 4096;              // names and numbers are short
  // A full row of max_columns numbers is about 1.2 MB (~20 bytes a value);
  // a longer line is not an export, and reading stops there.
  std::uint64_t max_line_bytes = 4u << 20;
  int max_rate_hz = 10000;                    // Vicon cameras run at up to 2000 Hz
  std::int64_t max_frame = 1000000000000;     // a year at 10 kHz is 3e11
  int max_sub_frame = 1000;
  double max_abs_position_mm = 1e6;           // 1 km: larger than any capture volume
  double max_abs_rotation_deg = 3600;         // ten turns (unwrapped helical angles exceed 180)
  double max_abs_rotation_rad = 62.832;
};
inline constexpr ViconCsvLimits kViconCsvLimits{};

struct ViconCsvOptions {
  // Data rows shorter than the block (an interrupted export) become rows with
  // every value missing instead of an error. They still need frame and sub frame.
  bool short_rows_are_missing = false;
  // Accept "0,5" as 0.5 in ';'-delimited files (Tracker's Local Numeric Format).
  bool allow_decimal_comma = false;
};

// Parses the text of a Vicon CSV export; `label` names it in errors.
Expected<ViconCsv> ParseViconCsv(std::string_view text, const std::string& label,
                                 const ViconCsvOptions& options = {});
// Reads and parses a file.
Expected<ViconCsv> ReadViconCsv(const std::filesystem::path& path,
                                const ViconCsvOptions& options = {});

// The file text: every block with its five header rows (names row padded to
// the full width, no trailing delimiters otherwise), values in the shortest
// form that reads back exactly, missing values as empty cells, blocks
// separated by one blank line, csv.delimiter and CRLF when csv.crlf.
std::string FormatViconCsv(const ViconCsv& csv);
Status WriteViconCsv(const std::filesystem::path& path, const ViconCsv& csv);

// What a block holds, for `lifmcr info`.
struct ViconBlockSummary {
  std::string name;
  int rate_hz = 0;
  std::vector<std::string> subjects;
  size_t num_entities = 0;         // markers, segments or objects
  std::vector<std::string> units;  // distinct units of the data columns
  size_t num_frames = 0;           // data rows
  int64_t first_frame = 0;         // 0 when there are no rows
  int64_t last_frame = 0;
  // Per subject (same order): rows where any of its columns is missing.
  std::vector<size_t> frames_with_missing;
  // "Trajectories: 100 Hz, 135 frames 1..135, 51 entities, subjects boite (0 frames with
  // missing data), Daphnee (17 ...), units mm"
  std::string OneLine() const;
};
ViconBlockSummary Summarize(const ViconBlock& block);
std::vector<ViconBlockSummary> Summarize(const ViconCsv& csv);

}  // namespace lifmcr
