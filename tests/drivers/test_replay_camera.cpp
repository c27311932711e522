// ReplayCamera on sequences written with WriteBmp in a temporary folder:
// order, ids, gaps, pixels, pacing modes, unreadable files, underruns.

#include "drivers/camera_factory.h"
#include "drivers/replay_camera.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace lifmcr {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

constexpr int kWidth = 33;  // odd: BMP rows are padded, pooled rows are not
constexpr int kHeight = 17;

// Pixel (x, y) of frame `number`: a value that differs per frame and place.
std::uint8_t PixelOf(std::int64_t number, int x, int y, int channel = 0) {
  return static_cast<std::uint8_t>(number * 7 + x * 3 + y * 5 + channel * 11);
}

void WriteFrames(const std::filesystem::path& sequence, const std::string& serial,
                 const std::vector<std::int64_t>& numbers,
                 PixelFormat format = PixelFormat::kMono8) {
  std::filesystem::create_directories(layout::CameraDir(sequence, serial));
  for (std::int64_t number : numbers) {
    OwnedImage image = OwnedImage::Allocate(kWidth, kHeight, format);
    const int channels = BytesPerPixel(format);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x)
        for (int c = 0; c < channels; ++c)
          image.View().Row(y)[x * channels + c] = PixelOf(number, x, y, c);
    ASSERT_TRUE(WriteBmp(layout::RawFramePath(sequence, serial, number), image.View()));
  }
}

std::vector<Frame> DrainAll(ReplayCamera& camera, std::vector<Frame>* failed = nullptr) {
  std::vector<Frame> frames;
  while (!camera.Finished()) {
    auto next = camera.NextFrame(milliseconds(2000));
    EXPECT_TRUE(next.ok());
    if (!next.ok() || !next->has_value()) continue;
    if ((*next)->status == FrameStatus::kOk)
      frames.push_back(std::move(**next));
    else if (failed != nullptr)
      failed->push_back(std::move(**next));
  }
  return frames;
}

TEST(ReplayCamera, ServesFramesInOrderWithIdsTimestampsAndPixels) {
  test::TempDir dir;
  WriteFrames(dir.path(), "R1", {0, 1, 2, 4, 5});  // frame 3 was dropped
  ReplayCamera camera(layout::CameraDir(dir.path(), "R1"),
                      {.camera_index = 2,
                       .trigger_period = milliseconds(100),
                       .pacing = ReplayPacing::kAsFastAsPossible});
  ASSERT_TRUE(camera.Open());
  EXPECT_EQ(camera.frame_count(), 5u);
  const CameraInfo info = camera.Info();
  EXPECT_EQ(info.serial, "R1");
  EXPECT_EQ(info.width, kWidth);
  EXPECT_EQ(info.height, kHeight);
  EXPECT_EQ(info.payload_bytes, static_cast<std::size_t>(kWidth * kHeight));
  ASSERT_TRUE(camera.Start());
  const std::vector<Frame> frames = DrainAll(camera);
  ASSERT_EQ(frames.size(), 5u);
  const std::vector<std::uint64_t> ids = {0, 1, 2, 4, 5};
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Frame& frame = frames[i];
    EXPECT_EQ(frame.frame_id, ids[i]);
    EXPECT_EQ(frame.camera_index, 2);
    EXPECT_EQ(frame.serial, "R1");
    EXPECT_EQ(frame.device_ns, static_cast<std::int64_t>(ids[i]) * 100'000'000);
    EXPECT_GT(frame.host_ns, 0);
    ASSERT_TRUE(frame.buffer);
    EXPECT_EQ(frame.image.data, frame.buffer->data);
    EXPECT_EQ(frame.image.stride_bytes, static_cast<std::size_t>(kWidth));
    for (int y = 0; y < kHeight; y += 4)
      for (int x = 0; x < kWidth; x += 5)
        ASSERT_EQ(frame.image.Row(y)[x], PixelOf(static_cast<std::int64_t>(ids[i]), x, y))
            << "frame " << ids[i] << " pixel " << x << "," << y;
  }
  const CameraStats stats = camera.Stats();
  EXPECT_EQ(stats.completed, 5u);
  EXPECT_EQ(stats.missing_ids, 1u);  // frame 3
  EXPECT_EQ(stats.failed, 0u);
  EXPECT_EQ(stats.underruns, 0u);
  // After the last frame: nothing more, after the timeout.
  auto after = camera.NextFrame(milliseconds(10));
  ASSERT_TRUE(after.ok());
  EXPECT_FALSE(after->has_value());
}

TEST(ReplayCamera, ColourFramesKeepTheirBgrBytes) {
  test::TempDir dir;
  WriteFrames(dir.path(), "C1", {7, 8}, PixelFormat::kBgr8);
  ReplayCamera camera(layout::CameraDir(dir.path(), "C1"),
                      {.pacing = ReplayPacing::kAsFastAsPossible});
  ASSERT_TRUE(camera.Open());
  EXPECT_EQ(camera.Info().format, PixelFormat::kBgr8);
  ASSERT_TRUE(camera.Start());
  const std::vector<Frame> frames = DrainAll(camera);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].image.Row(3)[5 * 3 + 2], PixelOf(8, 5, 3, 2));
}

TEST(ReplayCamera, OriginalTimingTakesTheTriggerPeriodsAsFastModeDoesNot) {
  test::TempDir dir;
  WriteFrames(dir.path(), "T1", {10, 11, 12, 13, 15});  // 5 periods from 10 to 15
  const milliseconds period(40);
  {
    ReplayCamera camera(layout::CameraDir(dir.path(), "T1"),
                        {.trigger_period = period, .pacing = ReplayPacing::kOriginal});
    ASSERT_TRUE(camera.Open());
    ASSERT_TRUE(camera.Start());
    const Clock::time_point start = Clock::now();
    std::vector<Clock::duration> arrivals;
    while (!camera.Finished()) {
      auto next = camera.NextFrame(milliseconds(30));  // shorter than a period: some nullopt
      ASSERT_TRUE(next.ok());
      if (next->has_value()) arrivals.push_back(Clock::now() - start);
    }
    ASSERT_EQ(arrivals.size(), 5u);
    EXPECT_GE(arrivals.back(), 5 * period);
    EXPECT_LT(arrivals.back(), 5 * period + milliseconds(150));
    EXPECT_GE(arrivals[3], 3 * period);  // frame 13
    EXPECT_LT(arrivals[0], milliseconds(30));
  }
  {
    ReplayCamera camera(layout::CameraDir(dir.path(), "T1"),
                        {.trigger_period = period, .pacing = ReplayPacing::kAsFastAsPossible});
    ASSERT_TRUE(camera.Open());
    ASSERT_TRUE(camera.Start());
    const Clock::time_point start = Clock::now();
    EXPECT_EQ(DrainAll(camera).size(), 5u);
    EXPECT_LT(Clock::now() - start, 2 * period);
  }
}

TEST(ReplayCamera, LoopServesTheSequenceAgainWithIncreasingIds) {
  test::TempDir dir;
  WriteFrames(dir.path(), "L1", {4, 5, 7});
  ReplayCamera camera(layout::CameraDir(dir.path(), "L1"),
                      {.trigger_period = milliseconds(10),
                       .pacing = ReplayPacing::kAsFastAsPossible,
                       .loop = true});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  std::vector<std::uint64_t> ids;
  std::vector<std::uint8_t> first_pixels;
  for (int i = 0; i < 7; ++i) {
    auto next = camera.NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
    ids.push_back((*next)->frame_id);
    first_pixels.push_back((*next)->image.Row(0)[0]);
    EXPECT_EQ((*next)->device_ns, static_cast<std::int64_t>(ids.back()) * 10'000'000);
  }
  EXPECT_FALSE(camera.Finished());
  EXPECT_EQ(ids, (std::vector<std::uint64_t>{4, 5, 7, 8, 9, 11, 12}));
  EXPECT_EQ(first_pixels[3], PixelOf(4, 0, 0));  // lap 2 serves file frame 4 again
  EXPECT_EQ(camera.Stats().missing_ids, 2u);     // 6 and 10; lap to lap (7 -> 8) is no gap
}

TEST(ReplayCamera, TruncatedFileIsAFailedFrameAndReplayGoesOn) {
  test::TempDir dir;
  WriteFrames(dir.path(), "X1", {0, 1, 2});
  const std::filesystem::path broken = layout::RawFramePath(dir.path(), "X1", 1);
  std::filesystem::resize_file(broken, std::filesystem::file_size(broken) - 20);
  ReplayCamera camera(layout::CameraDir(dir.path(), "X1"),
                      {.pacing = ReplayPacing::kAsFastAsPossible});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  std::vector<Frame> failed;
  const std::vector<Frame> good = DrainAll(camera, &failed);
  ASSERT_EQ(good.size(), 2u);
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_EQ(failed[0].frame_id, 1u);
  EXPECT_EQ(failed[0].status, FrameStatus::kError);
  EXPECT_FALSE(failed[0].buffer);
  EXPECT_EQ(failed[0].image.data, nullptr);
  const CameraStats stats = camera.Stats();
  EXPECT_EQ(stats.completed, 2u);
  EXPECT_EQ(stats.failed, 1u);
  EXPECT_EQ(stats.missing_ids, 0u);
}

TEST(ReplayCamera, HeldBuffersInOriginalTimingAreUnderruns) {
  test::TempDir dir;
  WriteFrames(dir.path(), "U1", {0, 1, 2, 3, 4, 5});
  ReplayCamera camera(
      layout::CameraDir(dir.path(), "U1"),
      {.pool_buffers = 2, .trigger_period = milliseconds(5), .pacing = ReplayPacing::kOriginal});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  std::vector<Frame> held;
  while (!camera.Finished()) {
    auto next = camera.NextFrame(milliseconds(100));
    ASSERT_TRUE(next.ok());
    if (next->has_value()) held.push_back(std::move(**next));
  }
  EXPECT_EQ(held.size(), 2u);
  const CameraStats stats = camera.Stats();
  EXPECT_EQ(stats.completed, 2u);
  EXPECT_EQ(stats.underruns, 4u);
  EXPECT_EQ(stats.missing_ids, 0u);  // each lost frame counted once
}

TEST(ReplayCamera, SoftwareTriggerPacingReleasesOneFramePerTrigger) {
  test::TempDir dir;
  WriteFrames(dir.path(), "S1", {0, 1, 2});
  ReplayCamera camera(layout::CameraDir(dir.path(), "S1"),
                      {.pacing = ReplayPacing::kSoftwareTrigger});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  auto none = camera.NextFrame(milliseconds(20));
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  ASSERT_TRUE(camera.SoftwareTrigger());
  auto one = camera.NextFrame(milliseconds(1000));
  ASSERT_TRUE(one.ok() && one->has_value());
  EXPECT_EQ((*one)->frame_id, 0u);
  auto again = camera.NextFrame(milliseconds(20));
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(again->has_value());
}

TEST(ReplayCamera, SoftwareTriggerIsAnErrorWhenTheCameraPacesItself) {
  test::TempDir dir;
  WriteFrames(dir.path(), "P1", {0});
  ReplayCamera camera(layout::CameraDir(dir.path(), "P1"));
  ASSERT_TRUE(camera.Open());
  EXPECT_FALSE(camera.SoftwareTrigger());
}

TEST(ReplayCamera, MissingFolderIsAnErrorNamingIt) {
  test::TempDir dir;
  ReplayCamera camera(dir / "TypeE_nothere");
  const Status status = camera.Open();
  ASSERT_FALSE(status);
  EXPECT_NE(status.error().message.find("TypeE_nothere"), std::string::npos)
      << status.error().message;
}

TEST(CameraFactory, MakesReplayAndAravisCamerasAndRejectsWhatItCannot) {
  test::TempDir dir;
  WriteFrames(dir.path(), "F1", {0, 1});
  CameraConfig config;
  config.serial = "F1";
  config.name = "cam0";
  config.driver.kind = DriverKind::kReplay;
  CameraFactoryOptions options;
  options.replay_sequence_dir = dir.path();
  options.replay_pacing = ReplayPacing::kAsFastAsPossible;
  auto replay = MakeCamera(config, 1, options);
  ASSERT_TRUE(replay.ok()) << replay.error().message;
  ASSERT_TRUE((*replay)->Open());
  ASSERT_TRUE((*replay)->Start());
  auto frame = (*replay)->NextFrame(milliseconds(1000));
  ASSERT_TRUE(frame.ok() && frame->has_value());
  EXPECT_EQ((*frame)->camera_index, 1);

  options.replay_sequence_dir.clear();
  auto no_sequence = MakeCamera(config, 1, options);
  ASSERT_FALSE(no_sequence.ok());
  EXPECT_NE(no_sequence.error().message.find("cam0"), std::string::npos);

  // A bad option is an error naming the camera and the field.
  options.replay_sequence_dir = dir.path();
  for (const auto& [field, spoil] :
       std::vector<std::pair<std::string, std::function<void(CameraFactoryOptions&)>>>{
           {"pool_buffers", [](CameraFactoryOptions& o) { o.pool_buffers = 1; }},
           {"trigger_period", [](CameraFactoryOptions& o) { o.trigger_period = {}; }},
           {"free_run_rate_hz", [](CameraFactoryOptions& o) { o.free_run_rate_hz = -1; }}}) {
    CameraFactoryOptions bad = options;
    spoil(bad);
    auto made = MakeCamera(config, 1, bad);
    ASSERT_FALSE(made.ok()) << field;
    EXPECT_NE(made.error().message.find("cam0"), std::string::npos) << made.error().message;
    EXPECT_NE(made.error().message.find(field), std::string::npos) << made.error().message;
  }
  auto negative_index = MakeCamera(config, -1, options);
  ASSERT_FALSE(negative_index.ok());
  EXPECT_NE(negative_index.error().message.find("camera_index"), std::string::npos)
      << negative_index.error().message;
  options.replay_sequence_dir.clear();

  // A GenTL camera is made; without a producer (no cti, nothing in
  // GENICAM_GENTL64_PATH) it cannot open, and says why.
  config.driver.kind = DriverKind::kGenTl;
  unsetenv("GENICAM_GENTL64_PATH");
  auto gentl = MakeCamera(config, 0, options);
  ASSERT_TRUE(gentl.ok()) << gentl.error().message;
  const Status gentl_open = (*gentl)->Open();
  ASSERT_FALSE(gentl_open);
  EXPECT_NE(gentl_open.error().message.find("GENICAM_GENTL64_PATH"), std::string::npos)
      << gentl_open.error().message;

  config.driver.kind = DriverKind::kAravis;
  config.driver.address = "Fake_1";
  config.trigger.mode = TriggerMode::kSoftware;
  config.roi = RoiConfig{0, 0, 64, 64};
  auto aravis = MakeCamera(config, 0, options);
  ASSERT_TRUE(aravis.ok());
  ASSERT_TRUE((*aravis)->Open());
  EXPECT_EQ((*aravis)->Info().width, 64);

  ViconConfig vicon;
  EXPECT_EQ(TriggerPeriod(vicon), std::chrono::nanoseconds(100'000'000));
  vicon.rate_hz = 100.0;
  vicon.trigger_divider = 4;
  EXPECT_EQ(TriggerPeriod(vicon), std::chrono::nanoseconds(40'000'000));
}

}  // namespace
}  // namespace lifmcr
