// Integration: lcm-logger (Debian liblcm-bin) records a `--rate max` replay of
// a small synthetic sequence on UDP multicast over loopback; the log is read
// back with LCM's log reader and checked (counts per channel, depth equal to
// the processing output, utimes increasing), and the generated jar decodes it
// headless. Needs root for the loopback multicast route (skipped otherwise).

#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/pipeline.h"
#include "apps/pipeline/process_settings.h"
#include "apps/pipeline/replay_runner.h"
#include "replay/bmp.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "tests/lcm_log_marker.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <map>
#include <sys/resource.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

// As the commands do before they run the pipeline (process_settings.h).
const std::unique_ptr<ProcessSettings> kProcessSettings = ProcessSettings::ForPipeline();

// A group and a UDP port of this process's own (tests/test_util.h says why
// both): another checkout's run of this test at the same time, on a fixed
// port, would reach this logger too.
const std::string kGroup = test::MulticastGroupOfThisProcess(73);
const std::string kUrl =
    "udpm://" + kGroup + ":" + std::to_string(test::MulticastPortOfThisProcess()) + "?ttl=0";
// The logger gets a large receive buffer (within net.core.rmem_max): a max-rate
// replay sends every message of a frame in a burst.

int Sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

class LoopbackMulticast : public ::testing::Test {
 protected:
  void SetUp() override {
    if (getuid() != 0) GTEST_SKIP() << "needs root to route multicast over loopback";
    if (Sh("command -v lcm-logger") != 0) GTEST_SKIP() << "lcm-logger missing (liblcm-bin)";
    ASSERT_EQ(Sh("ip link set lo multicast on"), 0);
    // Only the route this fixture added is removed again.
    added_route_ = Sh("ip route add " + kGroup + "/32 dev lo") == 0;
  }
  void TearDown() override {
    if (added_route_) Sh("ip route del " + kGroup + "/32 dev lo");
  }
  bool added_route_ = false;
};

TEST_F(LoopbackMulticast, LcmLoggerRecordsAMaxRateReplay) {
  test::TempDir dir;
  auto params = synth::MakePreset("small");
  ASSERT_TRUE(params.ok());
  params->camera.width_px = 320;
  params->camera.height_px = 240;
  params->rig.frames = 4;
  params->rig.cameras = 2;
  auto summary = synth::WriteSyntheticDataset(dir / "data", *params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const std::string log_path = (dir / "run.lcmlog").string();

  const pid_t logger = fork();
  ASSERT_GE(logger, 0);
  if (logger == 0) {
    // lcm-logger takes messages on one thread and queues at most 30 per
    // subscription (LCM's default; 1.3.1 has no option to raise it): starved
    // of CPU by other load, it drops the newest beyond that. A logger beside
    // a rig is given priority over the processing it records; so it is here
    // (the fixture runs as root).
    (void)setpriority(PRIO_PROCESS, 0, -10);
    execlp("lcm-logger", "lcm-logger", "-q", "-f", "-c", "LIFMCR_.*",
           ("--lcm-url=" + kUrl + "&recv_buf_size=4194304").c_str(), log_path.c_str(),
           nullptr);
    _exit(127);
  }
  // The logger matches LIFMCR_.*, so it logs the markers (the counts below
  // skip them).
  ASSERT_TRUE(test::PublishUntilLogged(kUrl, log_path, "LIFMCR_TEST_MARKER_READY"))
      << "lcm-logger did not log a marker within 60 s";

  ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate.kind = ReplayRate::Kind::kMax;
  options.pipeline.publisher.url = kUrl;
  auto result = RunReplay(options);
  ASSERT_TRUE(test::PublishUntilLogged(kUrl, log_path, "LIFMCR_TEST_MARKER_END"))
      << "lcm-logger did not log a marker within 60 s";
  kill(logger, SIGINT);
  int status = 0;
  waitpid(logger, &status, 0);
  ASSERT_TRUE(result.ok()) << result.error().message;
  ASSERT_TRUE(WIFEXITED(status)) << "lcm-logger did not exit cleanly";
  const PipelineReport& r = result->report;
  ASSERT_EQ(r.processed, 8u) << r.FinalReport();

  lcm::LogFile log(log_path, "r");
  ASSERT_TRUE(log.good());
  std::map<std::string, int> count;
  std::map<std::string, std::int64_t> last_utime;
  std::map<std::pair<std::string, std::int64_t>, lifmcr_lcm::depth_image_t> depth;
  std::int64_t last_event = -1;
  std::vector<std::int64_t> vicon_frames;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    ++count[event->channel];
    // (Receive timestamps of fragmented messages may go back a little; the
    // event numbers and each channel's utimes must increase.)
    EXPECT_GT(event->eventnum, last_event);
    last_event = event->eventnum;
    std::int64_t utime = 0;
    if (event->channel.ends_with("_DEPTH")) {
      lifmcr_lcm::depth_image_t m;
      ASSERT_GE(m.decode(event->data, 0, event->datalen), 0);
      utime = m.utime;
      if (m.geometry == lifmcr_lcm::depth_image_t::GEOMETRY_TOTALLY_FOCUSED)
        depth[{m.serial, m.frame_id}] = m;
      else
        EXPECT_EQ(m.geometry, lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID);
    } else if (event->channel.ends_with("_PREVIEW") || event->channel.ends_with("_TF")) {
      lifmcr_lcm::preview_image_t m;
      ASSERT_GE(m.decode(event->data, 0, event->datalen), 0);
      utime = m.utime;
    } else if (event->channel == kViconChannel) {
      lifmcr_lcm::vicon_frame_t m;
      ASSERT_GE(m.decode(event->data, 0, event->datalen), 0);
      utime = m.utime;
      vicon_frames.push_back(m.vicon_frame);
    } else {
      continue;
    }
    EXPECT_GE(utime, last_utime[event->channel]) << event->channel;
    last_utime[event->channel] = utime;
  }
  const auto layout = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(layout.ok());
  std::vector<std::string> serials;
  for (const auto& camera : layout->cameras) serials.push_back(camera.serial);
  for (const std::string& serial : serials) {
    EXPECT_EQ(count[CameraChannel(serial, "PREVIEW")], 4) << serial;
    // The dense (TF grid) and the per-lens depth of each frame.
    EXPECT_EQ(count[CameraChannel(serial, "DEPTH")], 2 * 4) << serial;
    EXPECT_EQ(count[CameraChannel(serial, "TF")], 4) << serial;
  }
  // Every message published is in the log: Vicon frames once each, in order.
  // (The last one or two of 32 were lost when the max-rate replay released
  // all 32 at once: more than the logger's queue of 30.)
  EXPECT_EQ(static_cast<std::uint64_t>(count[kViconChannel]), r.published_vicon)
      << ::testing::PrintToString(vicon_frames);
  for (std::size_t k = 1; k < vicon_frames.size(); ++k)
    EXPECT_GT(vicon_frames[k], vicon_frames[k - 1]);
  EXPECT_EQ(static_cast<std::uint64_t>(count[kStatsChannel]), r.published_stats);

  // Every logged depth map is the processing output for its frame.
  auto processor = DepthProcessor::ForSequence(summary->sequence_dir.string(), serials);
  ASSERT_TRUE(processor.ok()) << processor.error().message;
  for (const auto& camera : layout->cameras)
    for (std::int64_t frame_number : camera.frames) {
      const auto it = depth.find({camera.serial, frame_number});
      ASSERT_NE(it, depth.end()) << camera.serial << " " << frame_number;
      auto image = ReadBmp(*camera.FramePath(frame_number));
      ASSERT_TRUE(image.ok());
      Frame frame;
      frame.serial = camera.serial;
      frame.image = image->View();
      auto expected = (*processor)->Process(frame);
      ASSERT_TRUE(expected.ok() && expected->depth) << camera.serial;
      int w = 0, h = 0;
      auto decoded = DecodeDepth(it->second.data, it->second.scale, it->second.offset, &w, &h);
      ASSERT_TRUE(decoded.ok());
      ASSERT_EQ(decoded->size(), expected->depth->values.size());
      for (std::size_t k = 0; k < decoded->size(); ++k) {
        const float a = (*decoded)[k], b = expected->depth->values[k];
        ASSERT_EQ(std::isnan(a), std::isnan(b));
        if (!std::isnan(a)) {
          ASSERT_NEAR(a, b, it->second.scale);
        }
      }
    }

  // The lcm-spy jar: classes load and decode the logged messages, headless.
  const std::string jar = LIFMCR_LCM_JAR;
  if (!std::filesystem::exists(jar) || Sh("command -v javac") != 0) {
    GTEST_SKIP() << "no Java or no jar: the jar check is skipped";
  }
  const std::string classes = (dir / "classes").string();
  std::filesystem::create_directories(classes);
  const std::string cp = "/usr/share/java/lcm.jar:" + jar;
  ASSERT_EQ(Sh("javac -nowarn -cp " + cp + " -d " + classes + " " + LIFMCR_SOURCE_DIR +
               "/tests/apps/java/JarCheck.java"),
            0);
  const std::string out = (dir / "java.txt").string();
  ASSERT_EQ(std::system(("java -Djava.awt.headless=true -cp " + cp + ":" + classes + " JarCheck " +
                         log_path + " > " + out + " 2>&1")
                            .c_str()),
            0)
      << test::ReadFile(out);
  // Depth: the dense and the per-lens map of each of the 8 frames.
  EXPECT_EQ(test::ReadFile(out), "types 9 depth 16 preview 8\n");
}

}  // namespace
}  // namespace lifmcr::apps
