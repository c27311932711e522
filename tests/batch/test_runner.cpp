// `lifmcr batch run` on a synthetic rig written by the real `lifmcr synth`,
// with the real `lifmcr depth` and `lifmcr register` as the units' commands:
// the manifest, skipping what verifies, redoing what does not, failures with
// their message and log, units waiting for earlier plans, a busy unit, and a
// run stopped by SIGTERM or SIGKILL mid-unit and run again.

#include "batch/manifest.h"
#include "batch/merge.h"
#include "batch/plan.h"
#include "batch/runner.h"
#include "batch/status.h"
#include "tests/batch/batch_test_util.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <csignal>
#include <fcntl.h>
#include <fstream>
#include <sys/file.h>
#include <unistd.h>

namespace lifmcr::batch {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::string Lifmcr() { return lifmcr::test::LifmcrBinary().string(); }

// `lifmcr batch plan DATA --stage depth --per frames:1 --out PLAN [-- extra]`.
void PlanDepth(const fs::path& data, const fs::path& plan,
               const std::vector<std::string>& extra = {}) {
  std::vector<std::string> argv = {Lifmcr(), "batch", "plan",     data.string(), "--stage",
                                   "depth",  "--per", "frames:1", "--out",       plan.string()};
  if (!extra.empty()) {
    argv.push_back("--");
    argv.insert(argv.end(), extra.begin(), extra.end());
  }
  ASSERT_EQ(test::Run(argv), 0);
}

Expected<RunReport> RunIt(const fs::path& plan, int index, int count) {
  RunOptions o;
  o.plan_dir = plan;
  o.shard = {index, count};
  o.executable = lifmcr::test::LifmcrBinary();
  o.progress = nullptr;
  return RunShard(o);
}

TEST(BatchRun, RecordsSkipsAndRedoesWhatNoLongerVerifies) {
  lifmcr::test::TempDir dir;
  test::SynthSmallRig(dir / "data", 2);
  const fs::path plan = dir / "plan";
  PlanDepth(dir / "data", plan);
  Expected<Plan> p = ReadPlan(plan);
  ASSERT_TRUE(p) << p.error().message;
  ASSERT_EQ(p->units.size(), 4u);  // 2 cameras x 2 frames

  Expected<RunReport> r0 = RunIt(plan, 0, 2);
  ASSERT_TRUE(r0) << r0.error().message;
  EXPECT_EQ(r0->units, 2);
  EXPECT_EQ(r0->done, 2) << r0->BriefReport({0, 2});
  Expected<PlanStatus> half = ReadPlanStatus(plan);
  ASSERT_TRUE(half) << half.error().message;
  EXPECT_EQ(half->done, 2);
  EXPECT_EQ(half->left, 2);
  EXPECT_EQ(half->ExitCode(), 3);
  ASSERT_TRUE(RunIt(plan, 1, 2));

  std::map<std::string, ManifestEntry> entries = test::Entries(plan);
  ASSERT_EQ(entries.size(), 4u);
  for (const auto& [id, e] : entries) {
    EXPECT_EQ(e.state, UnitState::kDone) << id << ": " << e.BriefReport();
    EXPECT_EQ(e.attempt, 1);
    EXPECT_EQ(e.outputs.size(), 8u);  // no intrinsics: 3 TIFFs, 2 PNGs, the per-lens CSV, TIFF, PNG
    EXPECT_GT(e.peak_rss_kib, 0);
    EXPECT_GT(e.cpu_seconds, 0);
    EXPECT_TRUE(fs::is_regular_file(plan / e.log));
  }
  const auto outputs = test::ReadTree(plan / "units");

  // Everything verifies: nothing runs.
  Expected<RunReport> again = RunIt(plan, 0, 1);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->skipped, 4);
  EXPECT_EQ(again->ran, 0);

  // A truncated output and a stray file: status (manifest only) still counts
  // them done, run redoes exactly those two units.
  const Unit& a = p->units[0];
  const Unit& b = p->units[3];
  fs::resize_file(plan / a.writes[0], 100);
  lifmcr::test::WriteFile(plan / b.outputs / "stray.txt", "x");
  EXPECT_EQ(ReadPlanStatus(plan)->done, 4);
  Expected<RunReport> redo = RunIt(plan, 0, 1);
  ASSERT_TRUE(redo);
  EXPECT_EQ(redo->ran, 2);
  EXPECT_EQ(redo->done, 2);
  EXPECT_EQ(redo->skipped, 2);
  entries = test::Entries(plan);
  EXPECT_EQ(entries[a.id].attempt, 2);
  EXPECT_EQ(entries[b.id].attempt, 2);
  EXPECT_EQ(entries[p->units[1].id].attempt, 1);
  EXPECT_EQ(test::ReadTree(plan / "units"), outputs);  // the same bytes again, no stray file

  // A unit another process holds is passed over, not run twice.
  const int fd = ::open((plan / "locks" / (a.id + ".lock")).c_str(), O_RDWR);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  Expected<RunReport> busy = RunIt(plan, 0, 1);
  ::close(fd);
  ASSERT_TRUE(busy);
  EXPECT_EQ(busy->busy, 1);
  EXPECT_EQ(busy->skipped, 3);
  EXPECT_EQ(busy->ExitCode(), 1);

  Expected<MergeReport> merged = MergePlan(plan);
  ASSERT_TRUE(merged) << merged.error().message;
  EXPECT_EQ(merged->merged, 4);
  const std::string index = lifmcr::test::ReadFile(plan / "merged/outputs.csv");
  EXPECT_EQ(std::count(index.begin(), index.end(), '\n'), 1 + 4 * 8);
}

TEST(BatchRun, FailuresKeepTheirMessageAndLogAndWaitingUnitsDoNotRun) {
  lifmcr::test::TempDir dir;
  test::SynthSmallRig(dir / "data", 1);
  const fs::path plan = dir / "plan";
  PlanDepth(dir / "data", plan, {"--mla", (dir / "no_such_mla.xml").string()});
  Expected<RunReport> r = RunIt(plan, 0, 1);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->failed, 2);
  EXPECT_EQ(r->ExitCode(), 1);
  Expected<PlanStatus> status = ReadPlanStatus(plan);
  ASSERT_TRUE(status);
  EXPECT_EQ(status->failed, 2);
  EXPECT_EQ(status->ExitCode(), 1);
  for (const ManifestEntry& e : status->failures) {
    EXPECT_EQ(e.exit_code, 1);
    EXPECT_NE(e.message.find("no_such_mla.xml"), std::string::npos) << e.message;
    EXPECT_NE(lifmcr::test::ReadFile(plan / e.log).find("no_such_mla.xml"), std::string::npos);
  }
  // The CLI says the same, and a failed unit is retried by the next run.
  lifmcr::test::CommandResult cli = lifmcr::test::RunLifmcr("batch status " + plan.string());
  EXPECT_EQ(cli.exit_code, 1);
  EXPECT_NE(cli.out.find("2 units: 0 done, 2 failed, 0 left"), std::string::npos) << cli.out;
  EXPECT_NE(cli.out.find("log: " + plan.string() + "/logs/"), std::string::npos) << cli.out;
  ASSERT_TRUE(RunIt(plan, 0, 1));
  EXPECT_EQ(test::Entries(plan).begin()->second.attempt, 2);

  // Register after a calibration plan that has not run: its unit waits.
  ASSERT_EQ(test::Run({Lifmcr(), "batch", "plan", (dir / "data").string(), "--stage", "calibrate",
                       "--out", (dir / "cal").string()}),
            0);
  ASSERT_EQ(
      test::Run({Lifmcr(), "batch", "plan", (dir / "data").string(), "--stage", "register",
                 "--calibration-plan", (dir / "cal").string(), "--out", (dir / "reg").string()}),
      0);
  Expected<RunReport> waiting = RunIt(dir / "reg", 0, 1);
  ASSERT_TRUE(waiting);
  EXPECT_EQ(waiting->failed, 1);
  EXPECT_EQ(waiting->ran, 0);
  const ManifestEntry e = test::Entries(dir / "reg").begin()->second;
  EXPECT_EQ(e.attempt, 0);
  EXPECT_NE(e.message.find("needs unit 00_Synthetic/Sequence_00/"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("not run yet"), std::string::npos) << e.message;
  EXPECT_NE(lifmcr::test::ReadFile(dir / "reg" / e.log).find("not started"), std::string::npos);
}

TEST(BatchRun, RegisterThenEvaluateAndMergeTheTables) {
  lifmcr::test::TempDir dir;
  test::SynthSmallRig(dir / "data", 4);
  const std::string data = (dir / "data").string();
  ASSERT_EQ(test::Run({Lifmcr(), "batch", "plan", data, "--stage", "register",
                       "--reference-from-ground-truth", "--out", (dir / "reg").string()}),
            0);
  ASSERT_EQ(test::Run({Lifmcr(), "batch", "plan", data, "--stage", "evaluate",
                       "--registration-plan", (dir / "reg").string(), "--out",
                       (dir / "eval").string(), "--", "--split", "none", "--no-plots"}),
            0);
  // The evaluation waits for the registration.
  ASSERT_TRUE(RunIt(dir / "eval", 0, 1));
  EXPECT_NE(test::Entries(dir / "eval").begin()->second.message.find("not run yet"),
            std::string::npos);
  Expected<RunReport> reg = RunIt(dir / "reg", 0, 1);
  ASSERT_TRUE(reg) << reg.error().message;
  ASSERT_EQ(reg->done, 1);
  Expected<RunReport> ev = RunIt(dir / "eval", 0, 1);
  ASSERT_TRUE(ev) << ev.error().message;
  const ManifestEntry e = test::Entries(dir / "eval").begin()->second;
  ASSERT_EQ(e.state, UnitState::kDone) << e.BriefReport();
  EXPECT_TRUE(e.exit_code == 0 || e.exit_code == 3) << e.exit_code;

  Expected<MergeReport> merged = MergePlan(dir / "eval");
  ASSERT_TRUE(merged) << merged.error().message;
  const std::string csv = lifmcr::test::ReadFile(dir / "eval/merged/evaluation.csv");
  EXPECT_EQ(csv.rfind("scene,sequence,table,method,camera,correction,frames,", 0), 0u) << csv;
  // Camera X (not the ground truth's camera 0) against Vicon, relative and absolute.
  EXPECT_NE(csv.find("00_Synthetic,Sequence_00,relative,pnp,40398673,uncorrected,"),
            std::string::npos)
      << csv;
  EXPECT_NE(csv.find("00_Synthetic,Sequence_00,absolute,pnp,40398673,uncorrected,"),
            std::string::npos)
      << csv;
  const std::string md = lifmcr::test::ReadFile(dir / "eval/merged/evaluation.md");
  EXPECT_NE(md.find("| all | absolute | pnp | 40398673 | uncorrected |"), std::string::npos) << md;
  ASSERT_TRUE(MergePlan(dir / "reg"));
  const std::string rows = lifmcr::test::ReadFile(dir / "reg/merged/registration.csv");
  EXPECT_EQ(rows.rfind("scene,sequence,frame,camera,method,", 0), 0u) << rows;
  EXPECT_EQ(std::count(rows.begin(), rows.end(), '\n'), 1 + 4) << rows;  // camera X, 4 frames
}

// The first unit's log exists: its command has been started.
bool Started(const fs::path& plan, const Unit& unit) {
  return fs::exists(plan / LogPathOf(unit.id));
}

TEST(BatchRun, StoppedMidUnitByTermOrKillIsRedoneAndNothingElse) {
  lifmcr::test::TempDir dir;
  test::SynthSmallRig(dir / "data", 2);
  const fs::path serial = dir / "serial";
  PlanDepth(dir / "data", serial);
  ASSERT_TRUE(RunIt(serial, 0, 1));
  const auto expected = test::ReadTree(serial / "units");

  for (const int sig : {SIGTERM, SIGKILL}) {
    SCOPED_TRACE(sig == SIGTERM ? "SIGTERM to the runner" : "SIGKILL to runner and command");
    const fs::path plan = dir / ("plan_" + std::to_string(sig));
    PlanDepth(dir / "data", plan);
    const Plan p = *ReadPlan(plan);
    const pid_t pid = test::Spawn({Lifmcr(), "batch", "run", plan.string(), "--shard", "0/1"},
                                  dir / ("run_" + std::to_string(sig) + ".log"), true);
    ASSERT_TRUE(test::WaitUntil([&] { return Started(plan, p.units[1]); }, 60s));
    // SIGTERM reaches the runner only (it passes it on); SIGKILL reaches both,
    // as a node's loss or an OOM kill of the whole task would.
    if (sig == SIGTERM)
      ::kill(pid, SIGTERM);
    else
      ::kill(-pid, SIGKILL);
    EXPECT_EQ(test::Wait(pid), 128 + sig);
    Expected<std::optional<ManifestEntry>> cut = ReadManifestEntry(plan, p.units[1].id);
    ASSERT_TRUE(cut);
    if (sig == SIGTERM) {
      ASSERT_TRUE(*cut) << "a SIGTERM'ed unit is recorded";
      EXPECT_EQ((*cut)->state, UnitState::kFailed);
      EXPECT_NE((*cut)->message.find("interrupted by signal 15"), std::string::npos);
    } else {
      EXPECT_FALSE(*cut) << "a killed runner writes nothing: the unit is left";
    }
    EXPECT_FALSE(ReadManifestEntry(plan, p.units[2].id).value()) << "the run stopped there";
    // The killed command may outlive nothing: wait until its lock is free.
    ASSERT_TRUE(test::WaitUntil(
        [&] {
          const int fd = ::open((plan / "locks" / (p.units[1].id + ".lock")).c_str(), O_RDWR);
          const bool free = fd >= 0 && ::flock(fd, LOCK_EX | LOCK_NB) == 0;
          if (fd >= 0) ::close(fd);
          return free;
        },
        30s));

    Expected<RunReport> resumed = RunIt(plan, 0, 1);
    ASSERT_TRUE(resumed) << resumed.error().message;
    EXPECT_EQ(resumed->skipped, 1);
    EXPECT_EQ(resumed->done, 3);
    const auto entries = test::Entries(plan);
    for (const Unit& u : p.units)
      EXPECT_EQ(entries.at(u.id).attempt, u.id == p.units[1].id ? 2 : 1) << u.id;
    EXPECT_EQ(test::ReadTree(plan / "units"), expected);
  }
}

}  // namespace
}  // namespace lifmcr::batch
