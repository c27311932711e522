#pragma once
// `lifmcr batch merge PLAN_DIR`: the outputs of a plan's done units combined
// under PLAN_DIR/merged/ (each file written atomically):
//   every stage  outputs.csv      unit,path,bytes,xxh64 of every done unit's outputs
//   register     registration.csv scene,sequence + the columns of lifmcr register's
//                                 registration.csv, every unit's rows in plan order
//   evaluate     evaluation.csv   one row per sequence, table, method, camera and
//                                 correction: frames, translation and rotation RMSE and SD
//                evaluation.md    the same as a table, with per table, method, camera
//                                 and correction a row "all" over the sequences:
//                                 frames summed, RMSE pooled as sqrt(sum n*rmse^2 / sum n)
// Units not done are left out and listed; merging again overwrites.

#include "config/error.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::batch {

struct MergeReport {
  int merged = 0;                     // done units merged
  std::vector<std::string> not_done;  // units left out
  std::vector<std::string> files;     // written, relative to PLAN_DIR

  // "merged 4 of 5 units into merged/outputs.csv, merged/registration.csv; not done: ...".
  std::string BriefReport() const;
};

Expected<MergeReport> MergePlan(const std::filesystem::path& plan_dir);

}  // namespace lifmcr::batch
