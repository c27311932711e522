// `lifmcr record --publish`: the live pipeline beside the recorder. With a
// processing stage far slower than the triggers, frames are skipped for
// processing (counted) while the recording keeps every frame, byte for byte.

#include "config/rig_config.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "tests/acquisition/rig_fixture.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <map>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

TEST(RecordPublish, SlowProcessingSkipsPreviewsButRecordsEveryFrame) {
  test::TempDir dir;
  auto params = synth::MakePreset("small");
  ASSERT_TRUE(params.ok());
  params->rig.frames = 6;
  params->rig.cameras = 2;
  params->rig.scene = "plain";  // recording is under test, not the scene: the faster render
  auto summary = synth::WriteSyntheticDataset(dir / "synth", *params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const auto sequence = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(sequence.ok());

  RigConfig rig = test::TwoCameraRig();
  rig.vicon.source = ViconSourceKind::kNone;
  // 20 Hz triggers: depth takes far longer per frame, and the cameras'
  // first frames, placed on the trigger count by host time, keep 37 ms of
  // margin against a loaded machine's scheduling delays (50 Hz left 15 ms
  // and failed now and then under a parallel build).
  rig.vicon.rate_hz = 160;
  rig.vicon.udp.port = 51001;
  for (int c = 0; c < 2; ++c) {
    rig.cameras[c].serial = sequence->cameras[c].serial;
    rig.cameras[c].mla_file = layout::MlaXmlPath(summary->calibration_dir, rig.cameras[c].serial);
    rig.cameras[c].trigger.mode = TriggerMode::kHardware;
  }
  const fs::path rig_path = dir / "rig.yaml";
  test::WriteFile(rig_path, FormatRigConfig(rig));
  const auto result = test::RunLifmcr(
      "record --rig '" + rig_path.string() + "' --replay '" + summary->sequence_dir.string() +
      "' --out '" + (dir / "rec").string() + "' --duration 60 --publish --lcm memq://");
  EXPECT_EQ(result.exit_code, 0) << result.out << result.err;
  EXPECT_NE(result.out.find("stopped by: end of the replayed sequence"), std::string::npos)
      << result.out;
  EXPECT_NE(result.out.find("published (--publish):"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("frames in: 12 "), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("(all accounted for)"), std::string::npos) << result.out;
  EXPECT_EQ(result.out.find("skipped (newest wins): 0 "), std::string::npos)
      << "expected skipped frames with a slow stage:\n"
      << result.out;
  const fs::path copy = dir / "rec" / "00_Recording" / "seq";
  for (const auto& camera : sequence->cameras)
    for (std::int64_t f : camera.frames) {
      const fs::path a = *camera.FramePath(f);
      const fs::path b = layout::RawFramePath(copy, camera.serial, f);
      ASSERT_TRUE(fs::exists(b)) << b;
      // The same pixels (the recorder writes its own BMP header style).
      const auto pa = ReadBmp(a), pb = ReadBmp(b);
      ASSERT_TRUE(pa.ok() && pb.ok()) << b;
      EXPECT_EQ(pa->width, pb->width);
      EXPECT_TRUE(pa->pixels == pb->pixels) << b;
    }
}

// The rig file's processing: and lcm: sections configure `record --publish`
// (no --lcm flag): the URL (an LCM log file), the channel prefix, previews
// on or off and their size, the skip policy (block: every frame processed)
// and processing.enabled (false: previews only).
TEST(RecordPublish, RigFileProcessingAndLcmSectionsTakeEffect) {
  test::TempDir dir;
  auto params = synth::MakePreset("small");
  ASSERT_TRUE(params.ok());
  params->rig.frames = 4;
  params->rig.cameras = 2;
  auto summary = synth::WriteSyntheticDataset(dir / "synth", *params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const auto sequence = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(sequence.ok());
  for (const bool previews : {true, false}) {
    RigConfig rig = test::TwoCameraRig();
    rig.vicon.source = ViconSourceKind::kNone;
    rig.vicon.rate_hz = 160;  // 20 Hz triggers
    rig.vicon.udp.port = 51001;
    for (int c = 0; c < 2; ++c) {
      rig.cameras[c].serial = sequence->cameras[c].serial;
      rig.cameras[c].mla_file =
          layout::MlaXmlPath(summary->calibration_dir, rig.cameras[c].serial);
      rig.cameras[c].trigger.mode = TriggerMode::kHardware;
    }
    const fs::path log = dir / (previews ? "with.lcmlog" : "without.lcmlog");
    rig.processing.enabled = false;
    rig.processing.skip_policy = SkipPolicy::kBlock;
    rig.processing.threads = 1;
    rig.processing.preview_max_px = 64;
    rig.lcm.url = "file://" + log.string() + "?mode=w";
    rig.lcm.channel_prefix = "REC_TEST";
    rig.lcm.publish_previews = previews;
    const fs::path rig_path = dir / "rig.yaml";
    test::WriteFile(rig_path, FormatRigConfig(rig));
    const fs::path out = dir / (previews ? "rec1" : "rec2");
    const auto result =
        test::RunLifmcr("record --rig '" + rig_path.string() + "' --replay '" +
                        summary->sequence_dir.string() + "' --out '" + out.string() +
                        "' --duration 60 --publish");
    ASSERT_EQ(result.exit_code, 0) << result.out << result.err;
    EXPECT_NE(result.out.find("frames in: 8 "), std::string::npos) << result.out;
    EXPECT_NE(result.out.find("skipped (newest wins): 0 "), std::string::npos) << result.out;
    EXPECT_NE(result.out.find("(all accounted for)"), std::string::npos) << result.out;

    lcm::LogFile file(log.string(), "r");
    ASSERT_TRUE(file.good()) << log;
    std::map<std::string, int> channels;
    int largest_side = 0;
    while (const lcm::LogEvent* event = file.readNextEvent()) {
      ++channels[event->channel];
      EXPECT_TRUE(event->channel.starts_with("REC_TEST_")) << event->channel;
      if (event->channel.ends_with("_PREVIEW")) {
        lifmcr_lcm::preview_image_t m;
        ASSERT_GE(m.decode(event->data, 0, event->datalen), 0);
        largest_side = std::max({largest_side, static_cast<int>(m.width),
                                 static_cast<int>(m.height)});
      }
      EXPECT_FALSE(event->channel.ends_with("_DEPTH")) << "processing.enabled is false";
    }
    EXPECT_GT(channels["REC_TEST_STATS"], 0);
    int preview_messages = 0;
    for (const auto& camera : sequence->cameras)
      preview_messages += channels["REC_TEST_" + camera.serial + "_PREVIEW"];
    EXPECT_EQ(preview_messages, previews ? 8 : 0);
    if (previews) {
      EXPECT_EQ(largest_side, 64);
    }
  }
}

}  // namespace
}  // namespace lifmcr
