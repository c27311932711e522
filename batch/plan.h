#pragma once
// A batch plan: units of work over a dataset, each one `lifmcr` command and
// the outputs it writes, stored as PLAN_DIR/plan.jsonl (docs/batch.md gives
// every field). Line 1 describes the plan, every further line is one unit:
//
//   {"lifmcr_batch_plan":1,"stage":"depth","per":"frames:4","dataset":"/data/LiFMCR",
//    "units":12,"command":"lifmcr batch plan ..."}
//   {"unit":"00_Synthetic/Sequence_00/40398673/000000-000003",
//    "scene":"00_Synthetic","sequence":"Sequence_00","camera":"40398673","reference":"",
//    "command":["lifmcr","depth","/data/.../Sequence_00","--camera","40398673",...],
//    "outputs":"units/00_Synthetic/Sequence_00/40398673/000000-000003",
//    "writes":["units/.../40398673_000000_virtual_depth.tiff", ...],"done_exits":[0],
//    "needs":[{"plan":"/plans/cal","unit":"00_Synthetic/Sequence_00/40398673"}]}
//
// A unit's command runs with PLAN_DIR as its working folder, so `outputs`
// and `writes` are relative to it (a plan moves with its folder); dataset
// paths and the folders of earlier plans it needs are absolute. The first
// word is always "lifmcr": `batch run` runs its own executable.
// Units belong to shards by their line: unit k (0-based) to shard k mod N.

#include "config/error.h"

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::batch {

inline constexpr int kPlanVersion = 1;
inline constexpr std::string_view kPlanFileName = "plan.jsonl";

enum class Stage { kDepth, kCalibrate, kRegister, kEvaluate };
std::string_view ToString(Stage stage);  // "depth", ...
Expected<Stage> ParseStage(std::string_view text);

// A unit of another plan that must be done before this unit can run.
struct UnitNeed {
  std::string plan;  // that plan's folder (absolute)
  std::string unit;  // its unit id
};

struct Unit {
  // Unique in the plan; '/'-separated names of letters, digits, '.', '_', '-'
  // (none "." or ".."), so it is a relative path under units/, manifest/, logs/.
  std::string id;
  std::string scene, sequence, camera;  // what it covers; camera empty for a whole sequence
  // register and evaluate: camera 0, whose map the others are registered to
  // (evaluate plans take it from the register plan); empty for other stages.
  std::string reference;
  std::vector<std::string> command;  // argv, command[0] == "lifmcr"
  std::string outputs;               // its output folder, relative to PLAN_DIR
  std::vector<std::string> writes;   // files it must write, relative to PLAN_DIR
  // The exit codes after which the unit is done (when it wrote `writes`): 0,
  // and for evaluate also 3 (written, but the hand-eye offsets could not be
  // estimated for some camera: the report says why; apps/cmd_evaluate.cpp).
  std::vector<int> done_exits = {0};
  std::vector<UnitNeed> needs;

  // "lifmcr depth /data/... --camera 40398673 ..." with every word that needs
  // it single-quoted for a POSIX shell.
  std::string CommandLine() const;
};

struct Plan {
  Stage stage = Stage::kDepth;
  std::string per;         // as given: "frames:4", "camera", "sequence"
  std::string dataset;     // absolute
  std::string planned_by;  // the `lifmcr batch plan` command line
  std::vector<Unit> units;

  // "depth plan of /data/LiFMCR: 12 units per frames:4".
  std::string BriefReport() const;
  // Units of shard `index` of `count`, in plan order (indices into units).
  std::vector<std::size_t> ShardUnits(int index, int count) const;
};

// Whether `id` is a valid unit id (see Unit::id).
bool IsValidUnitId(std::string_view id);

// plan.jsonl text of a plan (one JSON object per line, '\n' ends each).
std::string FormatPlan(const Plan& plan);
// Parses plan.jsonl text; errors name `label`, the line and the field.
Expected<Plan> ParsePlan(std::string_view text, const std::string& label);
// PLAN_DIR/plan.jsonl read and parsed.
Expected<Plan> ReadPlan(const std::filesystem::path& plan_dir);
// Writes PLAN_DIR/plan.jsonl atomically (batch/atomic_file.h).
Status WritePlan(const std::filesystem::path& plan_dir, const Plan& plan);

// `--shard I/N`: 0 <= I < N, 1 <= N <= 100000.
struct ShardSpec {
  int index = 0;
  int count = 1;

  static Expected<ShardSpec> Parse(std::string_view text);
  std::string ToString() const;  // "I/N"
};

}  // namespace lifmcr::batch
