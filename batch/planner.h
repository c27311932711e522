#pragma once
// `lifmcr batch plan DATASET --stage S [--per P] --out PLAN_DIR`: the units of
// one stage over every sequence and camera the dataset layer finds
// (replay/sequence.h: DATASET is a dataset root, a scene or a sequence).
//
//   stage      --per (default first)   one unit                      its command
//   depth      frames:N (16) | camera   N frames of one camera        lifmcr depth SEQ --camera S
//   --frame ... calibrate  camera                   one camera of a sequence      lifmcr calibrate
//   SEQ --camera S register   sequence | camera        a sequence / one camera X     lifmcr
//   register SEQ [--camera X] evaluate   sequence                 a sequence lifmcr evaluate SEQ
//   --registration ...
//
// Stages after the first refer to an earlier plan's outputs, and each such
// unit lists the units it needs (batch/plan.h, UnitNeed):
//   depth --calibration-plan CAL: --intrinsics from CAL's unit of the camera;
//   register --calibration-plan CAL: --reference (the map) and --intrinsics of
//     the reference camera's unit, --intrinsics of every other camera's unit;
//   evaluate --registration-plan REG: --registration of every REG unit of the
//     sequence and --reference (camera 0 of REG's units); with
//     --calibration-plan CAL also --map and --reference-poses.
// Words after `--` are appended to every unit's command as they are.

#include "batch/plan.h"
#include "config/error.h"

#include <string>
#include <vector>

namespace lifmcr::batch {

// `--per`: frames:N (N frames per unit, 1..100000), camera or sequence.
struct PerSpec {
  enum class Kind { kFrames, kCamera, kSequence };
  Kind kind = Kind::kFrames;
  int frames = 16;

  static Expected<PerSpec> Parse(std::string_view text);
  std::string ToString() const;
};

struct PlanOptions {
  std::string dataset;  // dataset root, scene or sequence folder (read only)
  Stage stage = Stage::kDepth;
  std::string per;                     // empty: the stage's default (table above)
  std::string out;                     // PLAN_DIR
  std::vector<std::string> cameras;    // only these serials (default: all)
  std::vector<std::string> sequences;  // only these sequences: SEQ or SCENE/SEQ (default: all)
  // depth: a cameras.yaml for every sequence, or "ground-truth" for each
  // sequence's GroundTruth/cameras.yaml (metric depth and point clouds).
  std::string intrinsics;
  std::string calibration_plan;   // depth, register, evaluate (above)
  std::string registration_plan;  // evaluate (required)
  std::string reference;          // register: one reference map folder for every sequence
  bool reference_from_ground_truth = false;  // register: each sequence's ground-truth map
  // register and evaluate: camera 0, whose map is the reference (default, per
  // sequence: the map's camera for --reference, the register plan's for
  // evaluate, GroundTruth/cameras.yaml's first camera, the first by serial;
  // batch/planner.cpp says why in this order).
  std::string reference_camera;
  std::vector<std::string> extra;  // words appended to every unit's command
  std::string planned_by;          // the command line, recorded in the plan

  // Every field against the stage: what is missing, what does not apply to it.
  Status Check() const;
};

// The plan (not written). Errors name the folder, file or option at fault.
Expected<Plan> MakePlan(const PlanOptions& options);

}  // namespace lifmcr::batch
