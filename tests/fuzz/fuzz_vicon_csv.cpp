// Vicon CSV export, then the summaries `lifmcr info` prints and the poses
// `lifmcr vicon` extracts.

#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  if (size < 1) return 0;
  ViconCsvOptions options;
  options.short_rows_are_missing = (data[0] & 1) != 0;
  options.allow_decimal_comma = (data[0] & 2) != 0;
  Expected<ViconCsv> csv = ParseViconCsv(fuzz::Text(data + 1, size - 1), "fuzz.csv", options);
  if (!csv) return 0;
  (void)Summarize(*csv);
  const std::vector<std::string> subjects = PoseSubjects(*csv);
  for (std::size_t i = 0; i < subjects.size() && i < 4; ++i) {
    (void)ExtractSubjectPoses(*csv, subjects[i], {});
  }
  Expected<ViconCsv> again = ParseViconCsv(FormatViconCsv(*csv), "again.csv", options);
  fuzz::Require(again.ok(), "a written CSV reads back");
  return 0;
}
