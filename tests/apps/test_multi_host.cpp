// A rig on two hosts, end to end through the binary: two network namespaces
// joined by veth pairs on a bridge in a third (a private subnet, multicast
// routed over the link, LCM at ttl=1), each host running `lifmcr replay
// --cameras` of one camera of a synthetic 2-camera rig with live
// registration, `lifmcr relate` on the reference camera's host, and a stock
// `lcm-logger` in the third namespace recording every channel:
//   - the relate stage's c0_from_cx per trigger equals the single process's
//     (`replay` of both cameras, its messages written by LCM's file://
//     provider) within 1e-6, with the same change-detection verdicts;
//   - the logger holds every channel of both hosts (and both hosts' STATS);
//   - each host records its camera (`record --replay --cameras`) and `lifmcr
//     merge` of the two recordings is the single-host recording byte for byte.
// Needs root and `ip` (network namespaces) and lcm-logger: skipped with the
// reason printed otherwise. The namespaces are deleted also when it fails.
// ~17 s of CPU (user + sys), 50-130 s wall on 2 shared cores: label `long`.
#include "config/rig_config.h"
#include "lcm_types/safe_decode.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "tests/apps/synthetic_rig_file.h"
#include "tests/child_process.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kFrames = 6;

int Sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

// Two hosts and a listener, each a network namespace, on one link: veth
// pairs into a bridge in the listener's namespace (multicast snooping off, so
// every group reaches every port), 10.77.0.0/24, multicast routed over the
// link in each. Deleted on destruction.
class Hosts {
 public:
  Hosts() {
    const std::string id = std::to_string(getpid());
    a_ = "lifmcrA" + id;
    b_ = "lifmcrB" + id;
    l_ = "lifmcrL" + id;
  }
  ~Hosts() {
    for (const std::string& ns : {a_, b_, l_}) Sh("ip netns del " + ns);
  }
  Hosts(const Hosts&) = delete;
  Hosts& operator=(const Hosts&) = delete;

  // Empty when the hosts are up, else why not.
  std::string Create() {
    const std::vector<std::string> steps = {
        "ip netns add " + a_,
        "ip netns add " + b_,
        "ip netns add " + l_,
        "ip -n " + l_ + " link add br0 type bridge",
        "ip -n " + l_ + " link set br0 type bridge mcast_snooping 0",
        "ip link add v0 netns " + a_ + " type veth peer name pa netns " + l_,
        "ip link add v0 netns " + b_ + " type veth peer name pb netns " + l_,
        "ip -n " + l_ + " link set pa master br0",
        "ip -n " + l_ + " link set pb master br0",
        "ip -n " + a_ + " addr add 10.77.0.1/24 dev v0",
        "ip -n " + b_ + " addr add 10.77.0.2/24 dev v0",
        "ip -n " + l_ + " addr add 10.77.0.3/24 dev br0",
        "ip -n " + a_ + " link set lo up",
        "ip -n " + a_ + " link set v0 up",
        "ip -n " + b_ + " link set lo up",
        "ip -n " + b_ + " link set v0 up",
        "ip -n " + l_ + " link set lo up",
        "ip -n " + l_ + " link set pa up",
        "ip -n " + l_ + " link set pb up",
        "ip -n " + l_ + " link set br0 up",
        "ip -n " + a_ + " route add 224.0.0.0/4 dev v0",
        "ip -n " + b_ + " route add 224.0.0.0/4 dev v0",
        "ip -n " + l_ + " route add 224.0.0.0/4 dev br0"};
    for (const std::string& step : steps)
      if (Sh(step) != 0) return "'" + step + "' failed";
    return {};
  }
  const std::string& a() const { return a_; }
  const std::string& b() const { return b_; }
  const std::string& listener() const { return l_; }

 private:
  std::string a_, b_, l_;
};

using test::Child;

// Every c0_from_cx of a log, by trigger; and every channel in it.
struct LogContents {
  std::map<std::int64_t, lifmcr_lcm::camera_extrinsics_t> extrinsics;
  std::map<std::string, int> channels;  // messages per channel
  std::set<std::string> stats_sources;  // pipeline_stats_t::source
};

LogContents ReadLog(const fs::path& path) {
  LogContents contents;
  lcm::LogFile log(path.string(), "r");
  EXPECT_TRUE(log.good()) << path;
  if (!log.good()) return contents;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    ++contents.channels[event->channel];
    if (event->channel.ends_with("_EXTRINSICS")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_extrinsics_t>(event->data, event->datalen);
      EXPECT_TRUE(m) << event->channel;
      if (m) {
        EXPECT_TRUE(contents.extrinsics.emplace(m->trigger_index, *m).second)
            << "trigger " << m->trigger_index << " twice on " << event->channel;
      }
    }
    if (event->channel.ends_with("_STATS")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::pipeline_stats_t>(event->data, event->datalen);
      if (m) contents.stats_sources.insert(m->source);
    }
  }
  return contents;
}

// Every file under `a` has the same bytes under `b`, and `b` has no other.
void ExpectSameTree(const fs::path& a, const fs::path& b) {
  std::set<fs::path> files_a, files_b;
  for (const auto& entry : fs::recursive_directory_iterator(a))
    if (entry.is_regular_file()) files_a.insert(fs::relative(entry.path(), a));
  for (const auto& entry : fs::recursive_directory_iterator(b))
    if (entry.is_regular_file()) files_b.insert(fs::relative(entry.path(), b));
  EXPECT_EQ(files_a, files_b);
  for (const fs::path& file : files_a) {
    if (files_b.count(file)) {
      EXPECT_EQ(test::ReadFile(a / file), test::ReadFile(b / file)) << file << " differs";
    }
  }
  std::printf("%zu files compared byte for byte\n", files_a.size());
}

TEST(MultiHost, TwoHostsAndOneRelateStageMatchTheSingleProcessAndMergeTheirRecordings) {
  if (getuid() != 0) GTEST_SKIP() << "needs root (network namespaces)";
  if (Sh("command -v ip") != 0) GTEST_SKIP() << "needs `ip` (iproute2)";
  if (Sh("command -v lcm-logger") != 0) GTEST_SKIP() << "needs lcm-logger (liblcm-bin)";
  Hosts hosts;
  if (const std::string why = hosts.Create(); !why.empty()) {
    std::printf("skipped: network namespaces unavailable: %s\n", why.c_str());
    GTEST_SKIP() << "network namespaces unavailable: " << why;
  }
  const auto start = Clock::now();
  test::TempDir dir;
  const test::CommandResult synth =
      test::RunLifmcr("synth --out " + (dir / "data").string() + " --preset small --frames " +
                      std::to_string(kFrames) + " --cameras 2 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  const test::CommandResult map = test::RunLifmcr(
      "register " + seq.string() +
      " --reference-from-ground-truth --observations ground-truth --frames 1 --out " +
      (dir / "map").string());
  ASSERT_EQ(map.exit_code, 0) << map.err;
  const std::string reference = (dir / "map" / "reference").string();

  // The single process: both cameras, its messages into a log by LCM's file provider.
  const fs::path single_log = dir / "single.lcmlog";
  const test::CommandResult single =
      test::RunLifmcr("replay " + seq.string() + " --rate max --rigid-mount --reference " +
                      reference + " --lcm 'file://" + single_log.string() + "?mode=w'");
  ASSERT_EQ(single.exit_code, 0) << single.out << single.err;
  const LogContents one = ReadLog(single_log);
  ASSERT_EQ(one.extrinsics.size(), static_cast<std::size_t>(kFrames));
  const std::string zero = one.extrinsics.begin()->second.reference_serial;
  const std::string x = one.extrinsics.begin()->second.serial;

  // Two hosts, one camera each; relate on the reference camera's host; the
  // logger on the third.
  const std::string url = "udpm://" + test::MulticastGroupOfThisProcess(77) + ":" +
                          std::to_string(test::MulticastPortOfThisProcess()) + "?ttl=1";
  const fs::path multi_log = dir / "multi.lcmlog";
  Child logger(hosts.listener(), {"lcm-logger", "--lcm-url=" + url, multi_log.string()},
               dir / "logger.txt");
  Child relate(hosts.a(),
               test::LifmcrArgv({"relate", "--lcm", url, "--rigid-mount", "--wait-ms", "120000",
                                 "--duration", "500"}),
               dir / "relate.txt");
  // `lifmcr monitor` on the third host: its one view at the end (not a terminal).
  Child monitor(hosts.listener(), test::LifmcrArgv({"monitor", "--lcm", url}), dir / "monitor.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(700));  // subscribed
  const auto replay = [&](const std::string& serial) {
    return test::LifmcrArgv({"replay", seq.string(), "--cameras", serial, "--rate", "max",
                             "--reference", reference, "--lcm", url});
  };
  Child host_a(hosts.a(), replay(zero), dir / "host_a.txt");
  Child host_b(hosts.b(), replay(x), dir / "host_b.txt");
  const int a_code = host_a.Wait(std::chrono::seconds(400));
  const int b_code = host_b.Wait(std::chrono::seconds(400));
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));  // the last datagrams
  relate.Signal(SIGINT);
  const int relate_code = relate.Wait(std::chrono::seconds(30));
  logger.Signal(SIGINT);
  logger.Wait(std::chrono::seconds(30));
  monitor.Signal(SIGINT);
  EXPECT_EQ(monitor.Wait(std::chrono::seconds(30)), 0) << monitor.Log();
  ASSERT_EQ(a_code, 0) << host_a.Log();
  ASSERT_EQ(b_code, 0) << host_b.Log();
  EXPECT_EQ(relate_code, 0) << relate.Log();
  EXPECT_NE(host_b.Log().find("poses (POSE channels): " + std::to_string(kFrames)),
            std::string::npos)
      << host_b.Log();
  EXPECT_NE(relate.Log().find("extrinsics: " + std::to_string(kFrames) + " published"),
            std::string::npos)
      << relate.Log();

  // The relate stage's extrinsics: the single process's, per trigger.
  LogContents two = ReadLog(multi_log);
  ASSERT_EQ(two.extrinsics.size(), one.extrinsics.size()) << relate.Log();
  double worst = 0;
  for (const auto& [trigger, want] : one.extrinsics) {
    ASSERT_TRUE(two.extrinsics.count(trigger)) << "trigger " << trigger;
    const lifmcr_lcm::camera_extrinsics_t& got = two.extrinsics.at(trigger);
    EXPECT_EQ(got.reference_serial, zero);
    EXPECT_EQ(got.serial, x);
    EXPECT_EQ(got.status, want.status);
    EXPECT_EQ(got.method, want.method);
    EXPECT_EQ(got.localisation, want.localisation);
    EXPECT_EQ(got.inliers, want.inliers);
    EXPECT_EQ(got.change_state, want.change_state) << "trigger " << trigger;
    EXPECT_EQ(got.departures_in_row, want.departures_in_row);
    // q and -q are one rotation.
    const double sign = got.q_wxyz[0] * want.q_wxyz[0] < 0 ? -1.0 : 1.0;
    for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(got.t_mm[k] - want.t_mm[k]));
    for (int k = 0; k < 4; ++k)
      worst = std::max(worst, std::abs(sign * got.q_wxyz[k] - want.q_wxyz[k]));
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c)
        worst = std::max(worst, std::abs(got.covariance[r][c] - want.covariance[r][c]));
    worst = std::max(worst, std::abs(got.rmse_px - want.rmse_px));
    worst = std::max(
        worst, std::abs(got.departure - want.departure) / std::max(1.0, std::abs(want.departure)));
  }
  std::printf("relate across hosts vs single process: %zu triggers, largest difference %.3g\n",
              one.extrinsics.size(), worst);
  EXPECT_LE(worst, 1e-6);

  // The logger on the third host heard every channel of both hosts.
  for (const auto& [channel, n] : one.channels)
    EXPECT_TRUE(two.channels.count(channel)) << channel << " (" << n << " in the single run)";
  for (const std::string& serial : {zero, x})
    EXPECT_EQ(two.channels["LIFMCR_" + serial + "_POSE"], kFrames) << serial;
  EXPECT_EQ(two.stats_sources.size(), 2u) << "one STATS source per host";
  std::printf("lcm-logger in the third namespace: %zu channels\n", two.channels.size());
  // The monitor: every host's cameras (a row each, their poses) and one
  // pipeline block per host, naming its cameras.
  const std::string view = monitor.Log();
  for (const std::string& serial : {zero, x}) {
    EXPECT_NE(view.find("\n" + serial + " "), std::string::npos) << serial << "\n" << view;
    EXPECT_NE(view.find("\n  " + serial + " "), std::string::npos) << "pose row\n" << view;
    EXPECT_NE(view.find(", cameras " + serial + " (stats"), std::string::npos) << view;
  }
  EXPECT_NE(view.find(zero + " <- " + x), std::string::npos) << "extrinsics\n" << view;

  // Each host records its own camera; the merge is the single-host recording.
  const RigConfig rig = test::SyntheticReplayRig("two_hosts", dir / "data", seq, {zero, x}, zero);
  const fs::path rig_path = dir / "rig.yaml";
  test::WriteFile(rig_path, FormatRigConfig(rig));
  const auto record = [&](const std::string& ns, const std::string& out,
                          const std::string& cameras) {
    std::vector<std::string> args = {"record",     "--rig", rig_path.string(),    "--replay",
                                     seq.string(), "--out", (dir / out).string(), "--duration",
                                     "120"};
    if (!cameras.empty()) args.insert(args.end(), {"--cameras", cameras});
    Child child(ns, test::LifmcrArgv(args), dir / (out + ".txt"));
    const int code = child.Wait(std::chrono::seconds(150));
    EXPECT_EQ(code, 0) << child.Log();
  };
  record("", "single_host", "");
  record(hosts.a(), "host_a", zero);
  record(hosts.b(), "host_b", x);
  const std::string recorded = "00_Recording/seq";
  const test::CommandResult merged = test::RunLifmcr(
      "merge " + (dir / "host_a" / recorded).string() + " " + (dir / "host_b" / recorded).string() +
      " --out " + (dir / "merged" / recorded).string());
  ASSERT_EQ(merged.exit_code, 0) << merged.out << merged.err;
  std::printf("%s", merged.out.c_str());
  EXPECT_NE(merged.out.find("camera " + x + " (from "), std::string::npos) << merged.out;
  ExpectSameTree(dir / "single_host", dir / "merged");
  std::printf("MultiHost: %.0f s\n", std::chrono::duration<double>(Clock::now() - start).count());
}

}  // namespace
}  // namespace lifmcr
