// `lifmcr batch plan|run|status|merge`: a whole dataset as units of work
// that Slurm job arrays and GNU parallel run as they are (docs/batch.md).
// The flags are parsed here; planning, running, the manifest, status and
// merging are batch/ (batch/planner.h, batch/runner.h, batch/status.h,
// batch/merge.h).

#include "apps/commands.h"
#include "batch/merge.h"
#include "batch/plan.h"
#include "batch/planner.h"
#include "batch/runner.h"
#include "batch/status.h"
#include "config/text_escape.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;

int Fail(const char* sub, const std::string& message, int code = 1) {
  std::cerr << "lifmcr batch " << sub << ": " << EscapeText(message) << "\n";
  return code;
}

// A unit's command parsed by its stage's own flags (the subcommand's CLI11
// set-up, not run): a plan whose commands `batch run` would refuse is never
// written. Returns the parser's message on failure.
Status CheckUnitCommand(const batch::Unit& unit) {
  CLI::App probe{"probe"};
  const std::string& stage = unit.command.size() > 1 ? unit.command[1] : std::string();
  CLI::App* sub = probe.add_subcommand(stage);
  // The returned command owns the variables its flags are parsed into: it
  // lives until the parse is over, and is never called.
  CommandRun keep;
  if (stage == "depth")
    keep = AddDepthCommand(*sub);
  else if (stage == "calibrate")
    keep = AddCalibrateCommand(*sub);
  else if (stage == "register")
    keep = AddRegisterCommand(*sub);
  else if (stage == "evaluate")
    keep = AddEvaluateCommand(*sub);
  else
    return Error{"unit " + unit.id + ": not a stage command: " + unit.CommandLine()};
  std::vector<const char*> argv;
  for (const std::string& word : unit.command) argv.push_back(word.c_str());
  try {
    probe.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError& e) {
    return Error{"unit " + unit.id + ": lifmcr " + stage + " refuses its command (" + e.what() +
                 "): " + unit.CommandLine()};
  }
  return Status::Ok();
}

struct PlanArgs {
  batch::PlanOptions options;
  std::string stage;
};

// The `lifmcr batch plan` command line as the plan records it.
std::string PlanCommandLine(const PlanArgs& a) {
  const batch::PlanOptions& o = a.options;
  std::string line = "lifmcr batch plan " + o.dataset + " --stage " + a.stage;
  if (!o.per.empty()) line += " --per " + o.per;
  line += " --out " + o.out;
  for (const std::string& c : o.cameras) line += " --camera " + c;
  for (const std::string& q : o.sequences) line += " --sequence " + q;
  if (!o.intrinsics.empty()) line += " --intrinsics " + o.intrinsics;
  if (!o.calibration_plan.empty()) line += " --calibration-plan " + o.calibration_plan;
  if (!o.registration_plan.empty()) line += " --registration-plan " + o.registration_plan;
  if (!o.reference.empty()) line += " --reference " + o.reference;
  if (o.reference_from_ground_truth) line += " --reference-from-ground-truth";
  if (!o.reference_camera.empty()) line += " --reference-camera " + o.reference_camera;
  if (!o.extra.empty()) {
    line += " --";
    for (const std::string& w : o.extra) line += " " + w;
  }
  return line;
}

int RunPlan(const PlanArgs& a) {
  batch::PlanOptions o = a.options;
  Expected<batch::Stage> stage = batch::ParseStage(a.stage);
  if (!stage) return Fail("plan", "--stage: " + stage.error().message, 2);
  o.stage = *stage;
  o.planned_by = PlanCommandLine(a);
  if (Status s = o.Check(); !s) return Fail("plan", s.error().message, 2);
  Expected<batch::Plan> plan = batch::MakePlan(o);
  if (!plan) return Fail("plan", plan.error().message);
  for (const batch::Unit& unit : plan->units)
    if (Status s = CheckUnitCommand(unit); !s) return Fail("plan", s.error().message, 2);
  const fs::path plan_dir = o.out;
  std::error_code ec;
  if (fs::exists(plan_dir / batch::kPlanFileName, ec)) {
    // The same units again keep the manifest valid; other units would not.
    Expected<batch::Plan> old = batch::ReadPlan(plan_dir);
    if (!old) return Fail("plan", old.error().message);
    batch::Plan same = *plan;
    same.planned_by = old->planned_by;
    if (batch::FormatPlan(same) != batch::FormatPlan(*old))
      return Fail("plan", (plan_dir / batch::kPlanFileName).string() +
                              " holds another plan (its units differ); plan into a new --out "
                              "folder, or remove the old plan folder first");
    std::printf("%s: unchanged (%s)\n", (plan_dir / batch::kPlanFileName).string().c_str(),
                plan->BriefReport().c_str());
    return 0;
  }
  if (Status s = batch::WritePlan(plan_dir, *plan); !s) return Fail("plan", s.error().message);
  std::printf("%s\nwrote %s; first unit:\n  %s\n", plan->BriefReport().c_str(),
              (plan_dir / batch::kPlanFileName).string().c_str(),
              plan->units.front().CommandLine().c_str());
  std::printf(
      "next: lifmcr batch run %s --shard I/N (for I in 0..N-1, e.g. "
      "scripts/cluster/lifmcr-array.sbatch), then lifmcr batch status %s\n",
      plan_dir.string().c_str(), plan_dir.string().c_str());
  return 0;
}

int RunRun(const std::string& plan_dir, const std::string& shard_text, bool quiet) {
  Expected<batch::ShardSpec> shard = batch::ShardSpec::Parse(shard_text);
  if (!shard) return Fail("run", shard.error().message, 2);
  batch::RunOptions o;
  o.plan_dir = plan_dir;
  o.shard = *shard;
  std::error_code ec;
  o.executable = fs::read_symlink("/proc/self/exe", ec);
  if (ec)
    return Fail("run",
                std::string("cannot find the lifmcr executable (/proc/self/exe): ") + ec.message());
  o.progress = quiet ? nullptr : stdout;
  Expected<batch::RunReport> report = batch::RunShard(o);
  if (!report) return Fail("run", report.error().message);
  return report->ExitCode();
}

int RunStatus(const std::string& plan_dir, bool list_left) {
  Expected<batch::PlanStatus> status = batch::ReadPlanStatus(plan_dir);
  if (!status) return Fail("status", status.error().message, 2);
  std::printf("%s\n", status->BriefReport().c_str());
  for (const batch::ManifestEntry& e : status->failures)
    std::printf("failed %s (attempt %d, %s): %s\n  log: %s\n", e.unit.c_str(), e.attempt,
                e.signal ? ("signal " + std::to_string(e.signal)).c_str()
                         : ("exit " + std::to_string(e.exit_code)).c_str(),
                EscapeText(e.message).c_str(), (fs::path(plan_dir) / e.log).string().c_str());
  const std::size_t shown =
      list_left ? status->left_units.size() : std::min<std::size_t>(5, status->left_units.size());
  for (std::size_t k = 0; k < shown; ++k) std::printf("left %s\n", status->left_units[k].c_str());
  if (shown < status->left_units.size())
    std::printf("... and %zu more left (--list-left lists them)\n",
                status->left_units.size() - shown);
  return status->ExitCode();
}

int RunMerge(const std::string& plan_dir) {
  Expected<batch::MergeReport> report = batch::MergePlan(plan_dir);
  if (!report) return Fail("merge", report.error().message);
  std::printf("%s\n", report->BriefReport().c_str());
  return report->not_done.empty() ? 0 : 3;
}

// A subcommand of `lifmcr batch` whose one positional argument is PLAN_DIR,
// parsed into `plan_dir`.
CLI::App* AddPlanDirSubcommand(CLI::App& app, const char* name, const char* description,
                               const char* footer, std::string& plan_dir,
                               const char* plan_dir_help = "Plan folder") {
  CLI::App* sub = app.add_subcommand(name, description);
  sub->footer(footer);
  sub->add_option("PLAN_DIR", plan_dir, plan_dir_help)->required();
  return sub;
}

}  // namespace

CommandRun AddBatchCommand(CLI::App& app) {
  app.require_subcommand(1);
  app.footer(
      "The cycle: `batch plan` writes PLAN_DIR/plan.jsonl (one unit per line: its lifmcr\n"
      "command and the outputs it writes); `batch run PLAN_DIR --shard I/N` runs shard I of N\n"
      "(one Slurm array task or GNU parallel job each; scripts/cluster/lifmcr-array.sbatch);\n"
      "after each unit a manifest entry with its outputs' sizes and XXH64 checksums is written\n"
      "atomically, so running a shard again skips what is done and verifies, and redoes what\n"
      "was cut off or failed; `batch status` counts done, failed and left; `batch merge`\n"
      "combines the outputs. Formats: docs/batch.md.\n"
      "Reads: the dataset's layout (plan), PLAN_DIR (run, status, merge); the units' commands\n"
      "read the dataset. Writes: only under PLAN_DIR (plan.jsonl, units/, logs/, manifest/,\n"
      "locks/, merged/); the dataset is never written.\n"
      "Exit codes: the subcommand's (lifmcr batch SUBCOMMAND --help); 2 usage error.");

  auto plan = std::make_shared<PlanArgs>();
  CLI::App* p =
      app.add_subcommand("plan", "Write the units of one stage over a dataset into PLAN_DIR");
  p->footer(
      "Stages and --per (default first): depth frames:N|camera (frames:16); calibrate camera;\n"
      "register sequence|camera; evaluate sequence. Later stages refer to earlier plans\n"
      "(--calibration-plan, --registration-plan) and their units wait for those units.\n"
      "Reads: the dataset's folder layout (no frame is opened), earlier plans, and where\n"
      "camera 0 comes from them GroundTruth/cameras.yaml and the map's intrinsics.yaml.\n"
      "Writes: PLAN_DIR/plan.jsonl, atomically; planning the same units again changes nothing,\n"
      "other units into a folder that holds a plan are refused. Each unit's command is checked\n"
      "against its stage's flags before anything is written.\n"
      "Exit codes: 0 written (or unchanged); 1 the dataset or an earlier plan cannot be used\n"
      "(the message names it); 2 usage error.");
  p->add_option("DATASET", plan->options.dataset,
                "Dataset root, scene or sequence folder (only read)")
      ->required();
  p->add_option("--stage", plan->stage, "depth, calibrate, register or evaluate")->required();
  p->add_option("--per", plan->options.per, "Unit size: frames:N, camera or sequence (see below)");
  p->add_option("--out", plan->options.out, "PLAN_DIR: the plan and every output of its units")
      ->required();
  p->add_option("--camera", plan->options.cameras,
                "Only these camera serials (repeat; default all)");
  p->add_option("--sequence", plan->options.sequences,
                "Only these sequences, SEQ or SCENE/SEQ (repeat)");
  p->add_option("--intrinsics", plan->options.intrinsics,
                "depth: cameras.yaml for metric depth and point clouds, or 'ground-truth' for each "
                "sequence's GroundTruth/cameras.yaml");
  p->add_option("--calibration-plan", plan->options.calibration_plan,
                "A calibrate plan: depth takes each camera's intrinsics.yaml from it, register the "
                "reference map and intrinsics, evaluate --map and --reference-poses");
  p->add_option("--registration-plan", plan->options.registration_plan,
                "evaluate: the register plan whose registration.csv files it evaluates (required)");
  p->add_option("--reference", plan->options.reference,
                "register: one reference map folder for every sequence");
  p->add_flag("--reference-from-ground-truth", plan->options.reference_from_ground_truth,
              "register: each sequence's map from its ground truth (lifmcr synth datasets)");
  p->add_option("--reference-camera", plan->options.reference_camera,
                "register, evaluate: camera 0, whose map the others are registered to "
                "(default: the map's camera, the register plan's, GroundTruth/cameras.yaml's "
                "first, the first by serial; docs/batch.md)");
  p->add_option("ARGS", plan->options.extra,
                "After --: words appended to every unit's command (e.g. -- --method both)");

  auto run_plan_dir = std::make_shared<std::string>();
  auto shard = std::make_shared<std::string>("0/1");
  auto quiet = std::make_shared<bool>(false);
  CLI::App* r = AddPlanDirSubcommand(
      app, "run", "Run one shard of a plan's units, resuming where it stopped",
      "Runs the units k with k mod N == I in plan order, one after another, each as its own\n"
      "lifmcr process (this executable) in PLAN_DIR, its output into PLAN_DIR/units/<unit>/,\n"
      "its stdout and stderr appended to PLAN_DIR/logs/<unit>.log. A unit with a done\n"
      "manifest entry whose outputs verify (sizes, XXH64) is skipped; any other is run from\n"
      "an empty output folder. Needs of earlier plans must be done there. A unit another\n"
      "process runs (PLAN_DIR/locks/<unit>.lock) is passed over. SIGTERM/SIGINT/SIGHUP\n"
      "(scancel, preemption) stop the running unit, record it failed, and end the run.\n"
      "Progress: a line as each unit starts and ends, with done/left and a time estimate.\n"
      "Reads: PLAN_DIR/plan.jsonl, its manifest, the manifests of the earlier plans its units\n"
      "need. Writes: PLAN_DIR/units/<unit>/, logs/<unit>.log, manifest/<unit>.json,\n"
      "locks/<unit>.lock.\n"
      "Exit codes: 0 every unit of the shard done; 1 some failed or busy, or PLAN_DIR could\n"
      "not be read or written (the message names it); 2 usage error; 128+signal when\n"
      "interrupted.",
      *run_plan_dir, "Plan folder (lifmcr batch plan --out)");
  r->add_option("--shard", *shard,
                "I/N: this shard I of N (0 <= I < N); Slurm: $SLURM_ARRAY_TASK_ID/N")
      ->capture_default_str();
  r->add_flag("--quiet", *quiet, "No progress lines");

  auto status_dir = std::make_shared<std::string>();
  auto list_left = std::make_shared<bool>(false);
  CLI::App* s = AddPlanDirSubcommand(
      app, "status", "Count a plan's units done, failed and left (manifest only)",
      "Prints the counts, the time and the largest peak RSS of the units that ran (what to\n"
      "ask Slurm for: --mem), each failure with its message and log, and the units left.\n"
      "Reads: PLAN_DIR/plan.jsonl and the manifest entries only (no output is hashed).\n"
      "Writes: nothing.\n"
      "Exit codes: 0 every unit done; 1 some failed; 3 none failed, some left; 2 usage error\n"
      "or unreadable plan.",
      *status_dir);
  s->add_flag("--list-left", *list_left, "List every unit left (default: the first 5)");

  auto merge_dir = std::make_shared<std::string>();
  CLI::App* m = AddPlanDirSubcommand(
      app, "merge", "Combine the outputs of a plan's done units under PLAN_DIR/merged/",
      "Reads: PLAN_DIR/plan.jsonl, the manifest, the done units' registration.csv or\n"
      "evaluation.json.\n"
      "Writes: merged/outputs.csv (every output: unit, path, bytes, xxh64); register plans\n"
      "merged/registration.csv (scene, sequence + registration.csv's columns); evaluate plans\n"
      "merged/evaluation.csv and evaluation.md (per sequence, and pooled over sequences).\n"
      "Exit codes: 0 every unit merged; 3 merged, but some units are not done (listed);\n"
      "1 an output could not be read or written.",
      *merge_dir);

  return [=]() {
    if (p->parsed()) return RunPlan(*plan);
    if (r->parsed()) return RunRun(*run_plan_dir, *shard, *quiet);
    if (s->parsed()) return RunStatus(*status_dir, *list_left);
    if (m->parsed()) return RunMerge(*merge_dir);
    return 2;
  };
}

}  // namespace lifmcr::apps
