// The LCM tools as a user starts them, beside `lifmcr replay SEQ --rate max`
// of a `medium` synthetic rig (2 cameras), as docs/lcm.md shows:
//   - the real `lcm-logger LOG`, with no options (no receive buffer, no
//     channel filter), records every message the replay reports published,
//     and every message is at most half of a stock receiver's UDP buffer
//     (net.core.rmem_default 212992 bytes on Debian), so a logger on a host
//     that scripts/setup.sh did not tune keeps up too;
//   - lcm-spy's own type discovery (lcm.spy.LCMTypeDatabase over lcm.jar and
//     the generated type jar), headless, decodes every message of every
//     lifmcr channel live.
// Both run on the default URL, moved to a group and port of this process's
// own through LCM_DEFAULT_URL (an environment variable, not a tool option) so
// other LCM traffic on the host stays out. Needs root for the loopback multicast
// route (skipped otherwise), like the other multicast tests.

#include "tests/lcm_log_marker.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

// A group and a UDP port of this process's own (tests/test_util.h says why
// both): two runs of these tests at once (ctest -j, another checkout) would
// otherwise each log the other's replay.
const std::string kGroup = test::MulticastGroupOfThisProcess(79);
const std::string kUrl =
    "udpm://" + kGroup + ":" + std::to_string(test::MulticastPortOfThisProcess()) + "?ttl=0";
constexpr int kStockReceiveBuffer = 212992;  // Debian's net.core.rmem_default

int Sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

struct Published {
  int previews = 0, depth = 0, tf = 0, extrinsics = 0, vicon = 0, stats = 0;
  int Total() const { return previews + depth + tf + extrinsics + vicon + stats; }
};

// "published: 4 previews, 4 depth, 4 TF, 0 extrinsics, 16 Vicon, 2 stats messages"
bool ParsePublished(const std::string& out, Published* p) {
  std::smatch m;
  if (!std::regex_search(out, m,
                         std::regex(R"(published: (\d+) previews, (\d+) depth, (\d+) TF, )"
                                    R"((?:(\d+) extrinsics, )?(\d+) Vicon, (\d+) stats messages)")))
    return false;
  p->previews = std::stoi(m[1]);
  p->depth = std::stoi(m[2]);
  p->tf = std::stoi(m[3]);
  p->extrinsics = m[4].matched ? std::stoi(m[4]) : 0;
  p->vicon = std::stoi(m[5]);
  p->stats = std::stoi(m[6]);
  return true;
}

class StockLcmTools : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    data_ = new test::TempDir;
    // The plain scene: the LCM tools are under test, not the scene (the faster render).
    const test::CommandResult synth =
        test::RunLifmcr("synth --out " + data_->path().string() +
                        " --preset medium --scene plain --frames 2 --cameras 2 --quiet");
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
  }
  static void TearDownTestSuite() {
    delete data_;
    data_ = nullptr;
  }
  void SetUp() override {
    if (getuid() != 0) GTEST_SKIP() << "needs root to route multicast over loopback";
    if (Sh("command -v lcm-logger") != 0) GTEST_SKIP() << "lcm-logger missing (liblcm-bin)";
    ASSERT_EQ(Sh("ip link set lo multicast on"), 0);
    added_route_ = Sh("ip route add " + kGroup + "/32 dev lo") == 0;
    ASSERT_EQ(setenv("LCM_DEFAULT_URL", kUrl.c_str(), 1), 0);
  }
  void TearDown() override {
    unsetenv("LCM_DEFAULT_URL");
    if (added_route_) Sh("ip route del " + kGroup + "/32 dev lo");
  }
  static fs::path Sequence() { return data_->path() / "00_Synthetic" / "Sequence_00"; }
  // `lifmcr replay SEQ --rate max` as a user runs it; what it says it published.
  static Published Replay() {
    const test::CommandResult replay =
        test::RunLifmcr("replay " + Sequence().string() + " --rate max");
    Published published;
    EXPECT_EQ(replay.exit_code, 0) << replay.out << replay.err;
    EXPECT_TRUE(ParsePublished(replay.out, &published)) << replay.out;
    // Per frame the dense (TF grid) and the per-lens depth.
    EXPECT_EQ(published.depth, 2 * 4) << replay.out;
    return published;
  }

  static test::TempDir* data_;
  bool added_route_ = false;
};

test::TempDir* StockLcmTools::data_ = nullptr;

TEST_F(StockLcmTools, LcmLoggerWithNoOptionsRecordsEveryMessage) {
  test::TempDir dir;
  const std::string log_path = (dir / "run.lcmlog").string();
  const pid_t logger = fork();
  ASSERT_GE(logger, 0);
  if (logger == 0) {
    execlp("lcm-logger", "lcm-logger", log_path.c_str(), nullptr);
    _exit(127);
  }
  // The logger logs every channel, the markers too (the counts below skip them).
  ASSERT_TRUE(test::PublishUntilLogged(kUrl, log_path, "LIFMCR_TEST_MARKER_READY"))
      << "lcm-logger did not log a marker within 60 s";
  const Published published = Replay();
  ASSERT_TRUE(test::PublishUntilLogged(kUrl, log_path, "LIFMCR_TEST_MARKER_END"))
      << "lcm-logger did not log a marker within 60 s";
  kill(logger, SIGINT);
  int status = 0;
  waitpid(logger, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "lcm-logger did not exit cleanly";

  lcm::LogFile log(log_path, "r");
  ASSERT_TRUE(log.good());
  Published logged;
  int largest = 0;
  std::string largest_channel;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    const std::string& c = event->channel;
    if (!c.starts_with("LIFMCR_")) continue;
    if (event->datalen > largest) {
      largest = event->datalen;
      largest_channel = c;
    }
    if (c.ends_with("_PREVIEW"))
      ++logged.previews;
    else if (c.ends_with("_DEPTH"))
      ++logged.depth;
    else if (c.ends_with("_TF"))
      ++logged.tf;
    else if (c == "LIFMCR_VICON")
      ++logged.vicon;
    else if (c == "LIFMCR_STATS")
      ++logged.stats;
  }
  std::printf(
      "lcm-logger recorded %d of %d messages; largest %d bytes (%s), %.2f of a stock "
      "receive buffer\n",
      logged.Total(), published.Total(), largest, largest_channel.c_str(),
      static_cast<double>(largest) / kStockReceiveBuffer);
  EXPECT_EQ(logged.previews, published.previews);
  EXPECT_EQ(logged.depth, published.depth);
  EXPECT_EQ(logged.tf, published.tf);
  EXPECT_EQ(logged.extrinsics, published.extrinsics);
  EXPECT_EQ(logged.vicon, published.vicon);
  EXPECT_EQ(logged.stats, published.stats);
  EXPECT_LE(largest, kStockReceiveBuffer / 2) << largest_channel;
}

TEST_F(StockLcmTools, LcmSpyTypeDiscoveryDecodesEveryChannelHeadless) {
  const std::string jar = LIFMCR_LCM_JAR;
  if (!fs::exists(jar) || Sh("command -v javac") != 0) GTEST_SKIP() << "no Java or no type jar";
  test::TempDir dir;
  const std::string classes = (dir / "classes").string();
  fs::create_directories(classes);
  const std::string cp = "/usr/share/java/lcm.jar:" + jar;
  ASSERT_EQ(Sh("javac -nowarn -cp " + cp + " -d " + classes + " " + LIFMCR_SOURCE_DIR +
               "/tests/apps/java/SpyDecode.java"),
            0);
  const std::string out = (dir / "spy.txt").string();
  // stdin is the pipe: closing it tells SpyDecode to print and exit.
  FILE* spy = popen(
      ("java -Djava.awt.headless=true -cp " + cp + ":" + classes + " SpyDecode > " + out + " 2>&1")
          .c_str(),
      "w");
  ASSERT_NE(spy, nullptr);
  for (int i = 0; i < 200 && test::ReadFile(out).find("ready") == std::string::npos; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_NE(test::ReadFile(out).find("ready"), std::string::npos) << test::ReadFile(out);
  const Published published = Replay();
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  ASSERT_EQ(pclose(spy), 0) << test::ReadFile(out);
  const std::string text = test::ReadFile(out);
  std::map<std::string, std::pair<int, int>> decoded;  // channel -> decoded, failed
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    std::smatch m;
    if (std::regex_match(line, m, std::regex(R"((LIFMCR_\S+) decoded (\d+) failed (\d+))")))
      decoded[m[1]] = {std::stoi(m[2]), std::stoi(m[3])};
  }
  Published seen;
  for (const auto& [channel, counts] : decoded) {
    EXPECT_EQ(counts.second, 0) << channel << " has messages lcm-spy cannot decode";
    if (channel.ends_with("_PREVIEW"))
      seen.previews += counts.first;
    else if (channel.ends_with("_DEPTH"))
      seen.depth += counts.first;
    else if (channel.ends_with("_TF"))
      seen.tf += counts.first;
    else if (channel == "LIFMCR_VICON")
      seen.vicon += counts.first;
    else if (channel == "LIFMCR_STATS")
      seen.stats += counts.first;
    else
      ADD_FAILURE() << "unexpected channel " << channel;
  }
  std::printf("lcm-spy's type discovery decoded %d of %d messages on %zu channels\n", seen.Total(),
              published.Total(), decoded.size());
  EXPECT_EQ(decoded.size(), 8u) << text;  // 3 per camera, Vicon, stats
  EXPECT_EQ(seen.previews, published.previews) << text;
  EXPECT_EQ(seen.depth, published.depth) << text;
  EXPECT_EQ(seen.tf, published.tf) << text;
  EXPECT_EQ(seen.extrinsics, published.extrinsics) << text;
  EXPECT_EQ(seen.vicon, published.vicon) << text;
  EXPECT_EQ(seen.stats, published.stats) << text;
}

}  // namespace
}  // namespace lifmcr
