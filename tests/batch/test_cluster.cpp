// The depth and registration plans of a synthetic 2-camera rig run as a real
// Slurm job array (slurm-wlm and munge from Debian: munged, slurmctld and
// slurmd on localhost, configured in a temporary folder, started and
// stopped here; root only) and by GNU parallel, through
// scripts/cluster/lifmcr-array.sbatch and the README's parallel line; the
// outputs must equal a serial run's byte for byte (depth and register write
// the same bytes whatever the number of threads: the serial run's and the
// shards' outputs were compared with diff -r). Then one array task is
// cancelled mid-unit (scancel) and the array submitted again: every unit
// ends done once, the cancelled one redone, nothing else.

#include "batch/manifest.h"
#include "batch/plan.h"
#include "batch/status.h"
#include "tests/batch/batch_test_util.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <sys/stat.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace lifmcr::batch {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

std::string Lifmcr() { return lifmcr::test::LifmcrBinary().string(); }

double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// The two plans of the gates: depth (2 frames per unit, metric with the
// ground truth's intrinsics) and register (each camera against the ground
// truth map of camera 0).
void PlanBoth(const fs::path& data, const fs::path& depth, const fs::path& reg) {
  ASSERT_EQ(test::Run({Lifmcr(), "batch", "plan", data.string(), "--stage", "depth", "--per",
                       "frames:2", "--intrinsics", "ground-truth", "--out", depth.string()},
                      depth.string() + ".plan.log"),
            0);
  ASSERT_EQ(test::Run({Lifmcr(), "batch", "plan", data.string(), "--stage", "register", "--per",
                       "camera", "--reference-from-ground-truth", "--out", reg.string()},
                      reg.string() + ".plan.log"),
            0);
}

void ExpectAllDone(const fs::path& plan) {
  Expected<PlanStatus> s = ReadPlanStatus(plan);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->ExitCode(), 0) << s->BriefReport();
  for (const ManifestEntry& e : s->failures) ADD_FAILURE() << e.unit << ": " << e.message;
}

// A synthetic rig and the serial run of both plans, the reference of every run.
class Serial {
 public:
  explicit Serial(const fs::path& dir) : dir_(dir) {
    const auto t = Clock::now();
    test::SynthSmallRig(dir / "data", 4);
    PlanBoth(dir / "data", dir / "serial_depth", dir / "serial_reg");
    for (const char* plan : {"serial_depth", "serial_reg"})
      EXPECT_EQ(
          test::Run({Lifmcr(), "batch", "run", (dir / plan).string(), "--shard", "0/1", "--quiet"}),
          0);
    depth_ = test::ReadTree(dir / "serial_depth/units");
    reg_ = test::ReadTree(dir / "serial_reg/units");
    std::printf(
        "synthetic rig and serial runs: %zu depth and %zu register output files in %.1f s\n",
        depth_.size(), reg_.size(), Since(t));
  }
  const fs::path& data() const { return dir_; }
  void ExpectSame(const fs::path& depth, const fs::path& reg) const {
    EXPECT_EQ(test::ReadTree(depth / "units"), depth_) << depth << " differs from the serial run";
    EXPECT_EQ(test::ReadTree(reg / "units"), reg_) << reg << " differs from the serial run";
  }

 private:
  fs::path dir_;
  std::map<std::string, std::string> depth_, reg_;
};

// munged, slurmctld and slurmd in the foreground as this test's children,
// configured in `dir`; scontrol, sbatch and the rest reach them through
// SLURM_CONF. Stopped (and reaped) by the destructor, also when a test fails.
class SlurmCluster {
 public:
  explicit SlurmCluster(const fs::path& dir) : dir_(dir) {}
  ~SlurmCluster() { Stop(); }
  SlurmCluster(const SlurmCluster&) = delete;
  SlurmCluster& operator=(const SlurmCluster&) = delete;

  // Empty on success, else what is missing or did not start.
  std::string Start() {
    for (const char* p : {"mungekey", "munged", "munge", "slurmctld", "slurmd", "sbatch", "squeue",
                          "scancel", "scontrol", "sinfo"})
      if (test::FindProgram(p).empty())
        return std::string(p) + " not found: scripts/setup.sh installs slurm-wlm and munge";
    fs::create_directories(dir_ / "state");
    fs::create_directories(dir_ / "spool");
    const std::string key = (dir_ / "munge.key").string();
    const std::string socket = (dir_ / "munge.socket").string();
    if (test::Run({test::FindProgram("mungekey"), "--create", "--keyfile", key, "--force"},
                  dir_ / "mungekey.log") != 0)
      return "mungekey failed: " + lifmcr::test::ReadFile(dir_ / "mungekey.log");
    ::chmod(key.c_str(), 0600);
    munged_ = test::Spawn(
        {test::FindProgram("munged"), "--foreground", "--force", "--key-file", key, "--socket",
         socket, "--pid-file", (dir_ / "munged.pid").string(), "--log-file",
         (dir_ / "munged.log").string(), "--seed-file", (dir_ / "munged.seed").string()},
        dir_ / "munged.out", false);
    if (!test::WaitUntil([&] { return fs::exists(socket); }, 10s)) return "munged did not start";

    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    std::string short_host = host;
    short_host = short_host.substr(0, short_host.find('.'));
    // Ports of this process's own, so two checkouts' tests do not meet.
    const int port = 20000 + static_cast<int>(::getpid() % 20000) * 2;
    const long cpus = std::max(1L, ::sysconf(_SC_NPROCESSORS_ONLN));
    const std::string d = dir_.string();
    std::string conf =
        "ClusterName=lifmcrtest\n"
        "SlurmctldHost=" +
        short_host +
        "(127.0.0.1)\n"
        "SlurmUser=root\nSlurmdUser=root\n"
        "AuthType=auth/munge\nAuthInfo=socket=" +
        socket +
        "\nCredType=cred/munge\n"
        "SlurmctldPort=" +
        std::to_string(port) + "\nSlurmdPort=" + std::to_string(port + 1) +
        "\n"
        "StateSaveLocation=" +
        d + "/state\nSlurmdSpoolDir=" + d +
        "/spool\n"
        "SlurmctldPidFile=" +
        d + "/slurmctld.pid\nSlurmdPidFile=" + d +
        "/slurmd.pid\n"
        "SlurmctldLogFile=" +
        d + "/slurmctld.log\nSlurmdLogFile=" + d +
        "/slurmd.log\n"
        "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n"
        "JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n"
        "SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\nMpiDefault=none\n"
        "ReturnToService=2\nMailProg=/bin/true\n"
        // SIGKILL 5 s after scancel's SIGTERM (default 30 s): a runner that
        // did not end on SIGTERM would show here as a slow test.
        "KillWait=5\n"
        // The script asks for --mem=2G; CR_Core does not count memory, but a
        // node must have what a job asks for.
        "NodeName=" +
        short_host + " NodeAddr=127.0.0.1 CPUs=" + std::to_string(cpus) +
        " RealMemory=4096 State=UNKNOWN\n"
        "PartitionName=test Nodes=" +
        short_host + " Default=YES MaxTime=INFINITE State=UP\n";
    lifmcr::test::WriteFile(dir_ / "slurm.conf", conf);
    ::setenv("SLURM_CONF", (dir_ / "slurm.conf").c_str(), 1);
    slurmctld_ =
        test::Spawn({test::FindProgram("slurmctld"), "-D", "-f", (dir_ / "slurm.conf").string()},
                    dir_ / "slurmctld.out", false);
    slurmd_ = test::Spawn({test::FindProgram("slurmd"), "-D", "-f", (dir_ / "slurm.conf").string()},
                          dir_ / "slurmd.out", false);
    if (!test::WaitUntil(
            [&] { return test::Capture("sinfo -h -o %T 2>/dev/null").out == "idle\n"; }, 30s))
      return "the node did not become idle: " + lifmcr::test::ReadFile(dir_ / "slurmctld.log");
    return "";
  }

  // sbatch of the project's array script for PLAN with `shards` tasks; the job id.
  std::string SubmitArray(const fs::path& plan, int shards) {
    const std::string script =
        std::string(LIFMCR_SOURCE_DIR) + "/scripts/cluster/lifmcr-array.sbatch";
    fs::create_directories(plan / "slurm");
    const test::Captured c = test::Capture(
        "LIFMCR=" + Lifmcr() + " sbatch --parsable --array=0-" + std::to_string(shards - 1) +
        " -D " + plan.parent_path().string() + " -o " + plan.string() + "/slurm/%A_%a.out " +
        script + " " + plan.string() + " " + std::to_string(shards) + " 2>&1");
    EXPECT_EQ(c.exit_code, 0) << c.out;
    return c.out.substr(0, c.out.find_first_of(";\n"));
  }

  // Waits until the job has left the queue.
  bool WaitForJob(const std::string& job, std::chrono::seconds timeout) {
    return test::WaitUntil(
        [&] { return test::Capture("squeue -h -j " + job + " 2>/dev/null").out.empty(); }, timeout);
  }

 private:
  void Stop() {
    if (slurmctld_ > 0) {
      test::Capture("scancel --partition=test 2>&1; scontrol shutdown 2>&1");
      for (pid_t* pid : {&slurmctld_, &slurmd_}) {
        if (*pid <= 0) continue;
        if (!test::WaitUntil([&] { return ::waitpid(*pid, nullptr, WNOHANG) == *pid; }, 15s)) {
          ::kill(*pid, SIGKILL);
          test::Wait(*pid);
        }
        *pid = 0;
      }
    }
    if (munged_ > 0) {
      ::kill(munged_, SIGTERM);
      test::Wait(munged_);
      munged_ = 0;
    }
    ::unsetenv("SLURM_CONF");
  }

  fs::path dir_;
  pid_t munged_ = 0, slurmctld_ = 0, slurmd_ = 0;
};

TEST(BatchCluster, SlurmJobArrayEqualsSerialAndResumesAfterScancel) {
  if (::geteuid() != 0)
    GTEST_SKIP() << "runs munged, slurmctld and slurmd as root (SlurmUser=root); not root here";
  lifmcr::test::TempDir dir;
  const Serial serial(dir.path());
  if (HasFatalFailure()) return;
  SlurmCluster cluster(dir / "slurm");
  const auto t_start = Clock::now();
  const std::string why = cluster.Start();
  ASSERT_EQ(why, "");
  std::printf("slurm: munged, slurmctld, slurmd up, node idle in %.1f s\n", Since(t_start));

  // Both plans as job arrays of 2 tasks.
  PlanBoth(dir / "data", dir / "array_depth", dir / "array_reg");
  auto t = Clock::now();
  const std::string depth_job = cluster.SubmitArray(dir / "array_depth", 2);
  const std::string reg_job = cluster.SubmitArray(dir / "array_reg", 2);
  ASSERT_TRUE(cluster.WaitForJob(depth_job, 120s));
  ASSERT_TRUE(cluster.WaitForJob(reg_job, 120s));
  std::printf("slurm: job arrays %s (depth) and %s (register), 2 tasks each, done in %.1f s\n",
              depth_job.c_str(), reg_job.c_str(), Since(t));
  ExpectAllDone(dir / "array_depth");
  ExpectAllDone(dir / "array_reg");
  serial.ExpectSame(dir / "array_depth", dir / "array_reg");
  for (const char* task : {"_0.out", "_1.out"})
    EXPECT_TRUE(fs::exists(dir / "array_depth/slurm" / (depth_job + task))) << "a log per task";

  // Task 1 cancelled while it runs its first unit (unit 1 of the plan), then
  // the same array again.
  const fs::path plan = dir / "cancel_depth";
  ASSERT_EQ(
      test::Run({Lifmcr(), "batch", "plan", (dir / "data").string(), "--stage", "depth", "--per",
                 "frames:2", "--intrinsics", "ground-truth", "--out", plan.string()}),
      0);
  const Plan p = *ReadPlan(plan);
  ASSERT_GE(p.units.size(), 4u);
  const std::string cut = p.units[1].id;
  t = Clock::now();
  const std::string job = cluster.SubmitArray(plan, 2);
  // Cancelled once the unit's first frame is written and its second is not:
  // half its outputs are there.
  const fs::path first_output = plan / p.units[1].writes.front();
  ASSERT_TRUE(test::WaitUntil([&] { return fs::exists(first_output); }, 60s));
  ASSERT_EQ(test::Capture("scancel " + job + "_1 2>&1").exit_code, 0);
  ASSERT_TRUE(cluster.WaitForJob(job, 120s));
  Expected<std::optional<ManifestEntry>> cancelled = ReadManifestEntry(plan, cut);
  ASSERT_TRUE(cancelled);
  ASSERT_TRUE(!*cancelled || (*cancelled)->state == UnitState::kFailed)
      << "the cancel came after the unit was done: " << (*cancelled)->BriefReport();
  const std::size_t left_behind = test::ReadTree(plan / p.units[1].outputs).size();
  std::printf("slurm: the cancelled unit left %zu of its %zu files\n", left_behind,
              p.units[1].writes.size());
  EXPECT_GT(left_behind, 0u);
  EXPECT_LT(left_behind, p.units[1].writes.size());
  Expected<PlanStatus> after_cancel = ReadPlanStatus(plan);
  ASSERT_TRUE(after_cancel);
  std::printf("slurm: task %s_1 cancelled during unit %s: %s; %s\n", job.c_str(), cut.c_str(),
              *cancelled ? (*cancelled)->BriefReport().c_str() : "no entry (left)",
              after_cancel->BriefReport().c_str());
  EXPECT_NE(after_cancel->ExitCode(), 0);

  const std::string again = cluster.SubmitArray(plan, 2);
  ASSERT_TRUE(cluster.WaitForJob(again, 120s));
  std::printf("slurm: array %s submitted again; cancel and rerun in %.1f s\n", again.c_str(),
              Since(t));
  ExpectAllDone(plan);
  const auto entries = test::Entries(plan);
  for (const Unit& u : p.units) EXPECT_EQ(entries.at(u.id).attempt, u.id == cut ? 2 : 1) << u.id;
  EXPECT_EQ(test::ReadTree(plan / "units"), test::ReadTree(dir / "serial_depth/units"));
  const std::string task1 = lifmcr::test::ReadFile(plan / "slurm" / (again + "_1.out"));
  EXPECT_NE(task1.find(cut + ": running (attempt 2)"), std::string::npos) << task1;
  EXPECT_NE(task1.find("skipped"), std::string::npos)
      << "nothing else of shard 1 is redone: " << task1;
}

TEST(BatchCluster, GnuParallelEqualsSerial) {
  const std::string parallel = test::FindProgram("parallel");
  ASSERT_NE(parallel, "") << "GNU parallel not found: scripts/setup.sh installs it";
  lifmcr::test::TempDir dir;
  const Serial serial(dir.path());
  if (HasFatalFailure()) return;
  PlanBoth(dir / "data", dir / "par_depth", dir / "par_reg");
  for (const char* plan : {"par_depth", "par_reg"}) {
    const auto t = Clock::now();
    // The README's line.
    const test::Captured c = test::Capture(parallel + " -j2 " + Lifmcr() + " batch run " +
                                           (dir / plan).string() + " --shard {}/2 ::: 0 1 2>&1");
    EXPECT_EQ(c.exit_code, 0) << c.out;
    std::printf("parallel -j2 ... %s: exit %d in %.1f s\n", plan, c.exit_code, Since(t));
    ExpectAllDone(dir / plan);
  }
  serial.ExpectSame(dir / "par_depth", dir / "par_reg");
}

}  // namespace
}  // namespace lifmcr::batch
