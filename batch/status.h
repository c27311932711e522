#pragma once
// `lifmcr batch status PLAN_DIR`: how far a plan is, from the plan and its
// manifest entries only (no output is opened or hashed, so it costs one small
// read per unit wherever the plan lies).

#include "batch/manifest.h"
#include "batch/plan.h"
#include "config/error.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::batch {

struct PlanStatus {
  Plan plan;
  int done = 0, failed = 0, left = 0;
  std::vector<ManifestEntry> failures;  // in plan order
  std::vector<std::string> left_units;  // in plan order
  double unit_seconds = 0;              // summed over done units
  std::int64_t peak_rss_kib = 0;        // the largest over units that ran to an end
  std::string peak_rss_unit;

  // "depth plan of /data: 12 units: 8 done, 1 failed, 3 left; 41.2 s of units done
  //  (5.2 s each), peak RSS 177 MiB (unit ...)".
  std::string BriefReport() const;
  // 0 every unit done; 1 some failed; 3 none failed, some left.
  int ExitCode() const;
};

Expected<PlanStatus> ReadPlanStatus(const std::filesystem::path& plan_dir);

}  // namespace lifmcr::batch
