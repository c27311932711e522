// The recorder's building blocks on real files: BMPs written from pooled
// buffers read back through replay/bmp.h (O_DIRECT on the real disk, the
// buffered path on tmpfs), the Vicon CSV appender read back through the
// dataset layer, and the frame counter's 16-bit wrap.
#include "acquisition/frame_id_unwrapper.h"
#include "acquisition/memory_camera.h"
#include "acquisition/raw_frame_writer.h"
#include "acquisition/vicon_csv_appender.h"
#include "replay/bmp.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sys/statfs.h>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

Frame TakeFrame(MemoryCamera& camera) {
  EXPECT_TRUE(camera.SoftwareTrigger().ok());
  auto next = camera.NextFrame(milliseconds(1000));
  EXPECT_TRUE(next.ok());
  EXPECT_TRUE(next->has_value());
  return std::move(**next);
}

void ExpectPattern(const OwnedImage& image, std::uint64_t frame_id) {
  std::uint64_t stamped = 0;
  std::memcpy(&stamped, image.pixels.data(), sizeof(stamped));
  EXPECT_EQ(stamped, frame_id);
  const int bpp = BytesPerPixel(image.format);
  for (int y = 0; y < image.height; ++y)
    for (int x = (y == 0 ? 8 : 0); x < image.width; ++x)
      for (int c = 0; c < bpp; ++c)
        ASSERT_EQ(image.pixels[(static_cast<std::size_t>(y) * image.width + x) * bpp + c],
                  MemoryCamera::PatternAt(x, y, c))
            << x << "," << y << "," << c;
}

struct WriterCase {
  PixelFormat format;
  int width;
};

class RawFrameWriterTest : public ::testing::TestWithParam<WriterCase> {};

TEST_P(RawFrameWriterTest, DirectOnDiskReadsBackExactly) {
  MemoryCameraOptions options;
  options.width = GetParam().width;
  options.height = 37;
  options.format = GetParam().format;
  MemoryCamera camera(options);
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Start().ok());
  const Frame frame = TakeFrame(camera);

  test::TempDir dir;  // under the system temp dir: the real disk here
  const fs::path path = dir / "frame.bmp";
  auto written = WriteRawFrame(path, frame, /*try_direct=*/true);
  ASSERT_TRUE(written.ok()) << written.error().message;
  EXPECT_EQ(written->file_bytes, fs::file_size(path));
  EXPECT_EQ(written->file_bytes, RawBmpFileBytes(options.width, options.height, options.format));
  struct statfs fs_info {};
  ASSERT_EQ(statfs(dir.path().c_str(), &fs_info), 0);
  constexpr long kTmpfsMagic = 0x01021994;
  if (fs_info.f_type != kTmpfsMagic) {
    EXPECT_EQ(written->path, WritePath::kDirect);
  }

  auto header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_TRUE(header->top_down);
  EXPECT_EQ(header->pixel_offset, kRawBmpPixelOffset);
  EXPECT_EQ(header->format, options.format);
  EXPECT_TRUE(header->palette_is_grey);
  auto image = ReadBmp(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  ExpectPattern(*image, frame.frame_id);
}

INSTANTIATE_TEST_SUITE_P(Formats, RawFrameWriterTest,
                         ::testing::Values(WriterCase{PixelFormat::kMono8, 64},
                                           WriterCase{PixelFormat::kMono8, 61},
                                           WriterCase{PixelFormat::kBgr8, 64},
                                           WriterCase{PixelFormat::kBgr8, 33}));

TEST(RawFrameWriter, BufferedPathReadsBackExactly) {
  MemoryCamera camera(MemoryCameraOptions{});
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Start().ok());
  const Frame frame = TakeFrame(camera);
  test::TempDir dir;
  const fs::path path = dir / "frame.bmp";
  auto written = WriteRawFrame(path, frame, /*try_direct=*/false);
  ASSERT_TRUE(written.ok()) << written.error().message;
  EXPECT_EQ(written->path, WritePath::kBuffered);
  auto image = ReadBmp(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  ExpectPattern(*image, frame.frame_id);
}

// tmpfs refused O_DIRECT before Linux 6.6 and takes it since; either way the
// file must come out whole.
TEST(RawFrameWriter, TmpfsWritesWhicheverPathItTakes) {
  if (!fs::is_directory("/dev/shm")) GTEST_SKIP() << "no /dev/shm (tmpfs) here";
  MemoryCamera camera(MemoryCameraOptions{});
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Start().ok());
  const Frame frame = TakeFrame(camera);
  const fs::path path =
      fs::path("/dev/shm") / ("lifmcr_rec_test_" + std::to_string(getpid()) + ".bmp");
  auto written = WriteRawFrame(path, frame, /*try_direct=*/true);
  ASSERT_TRUE(written.ok()) << written.error().message;
  auto image = ReadBmp(path);
  fs::remove(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  ExpectPattern(*image, frame.frame_id);
}

TEST(RawFrameWriter, UnwritablePathIsAnErrorNamingTheFile) {
  MemoryCamera camera(MemoryCameraOptions{});
  ASSERT_TRUE(camera.Open().ok());
  ASSERT_TRUE(camera.Start().ok());
  const Frame frame = TakeFrame(camera);
  int error_number = 0;
  auto written = WriteRawFrame("/nonexistent_dir_lifmcr/x.bmp", frame, true, &error_number);
  ASSERT_FALSE(written.ok());
  EXPECT_EQ(error_number, ENOENT);
  EXPECT_NE(written.error().message.find("/nonexistent_dir_lifmcr/x.bmp"), std::string::npos);
}

TEST(FrameIdUnwrapper, SixteenBitWrapSkipsZero) {
  FrameIdUnwrapper unwrapper;
  std::int64_t expected = 0;
  std::uint64_t id = 65400;
  for (int i = 0; i < 300; ++i) {
    const auto step = unwrapper.Next(id);
    EXPECT_FALSE(step.stale);
    EXPECT_EQ(step.index, expected);
    EXPECT_EQ(step.missing_before, 0);
    ++expected;
    id = id == 65535 ? 1 : id + 1;
  }
}

TEST(FrameIdUnwrapper, GapsAcrossTheWrapAreCountedAndStaleFramesFlagged) {
  FrameIdUnwrapper unwrapper;
  EXPECT_EQ(unwrapper.Next(65533).index, 0);
  auto step = unwrapper.Next(2);  // 65534, 65535, 1 lost
  EXPECT_EQ(step.index, 4);
  EXPECT_EQ(step.missing_before, 3);
  EXPECT_TRUE(unwrapper.Next(2).stale);      // repeated
  EXPECT_TRUE(unwrapper.Next(65535).stale);  // late
  step = unwrapper.Next(3);
  EXPECT_EQ(step.index, 5);
  EXPECT_EQ(step.missing_before, 0);
}

TEST(FrameIdUnwrapper, WideCountersArePlainNumbers) {
  FrameIdUnwrapper unwrapper;
  EXPECT_EQ(unwrapper.Next(100000).index, 0);
  const auto step = unwrapper.Next(100005);
  EXPECT_EQ(step.index, 5);
  EXPECT_EQ(step.missing_before, 4);
}

Pose MakePose(double angle, double x) {
  Pose pose = Pose::Identity();
  pose.linear() =
      Eigen::AngleAxisd(angle, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(x, -2 * x, 1000 + x);
  return pose;
}

TEST(ViconCsvAppender, EveryFrameIsACompleteLineTheDatasetReads) {
  test::TempDir dir;
  const fs::path path = dir / "sequence_01.csv";
  ViconPoseOptions pose_options;
  auto appender = ViconCsvAppender::Create(path, {"cam0", "plate"}, 80, pose_options);
  ASSERT_TRUE(appender.ok()) << appender.error().message;
  for (int f = 1; f <= 20; ++f) {
    ViconFrame frame;
    frame.vicon_frame = 100 + f;
    frame.objects.push_back(
        {"cam0", f == 7 ? std::nullopt : std::optional<Pose>(MakePose(0.01 * f, f))});
    frame.objects.push_back({"plate", MakePose(0.2, 5)});
    if (f == 3) frame.objects.push_back({"intruder", MakePose(0, 0)});
    ASSERT_TRUE(appender->Append(frame).ok());
    // After every frame the file on disk parses with all frames so far.
    auto csv = ReadViconCsv(path);
    ASSERT_TRUE(csv.ok()) << csv.error().message;
    ASSERT_EQ(csv->blocks.size(), 1u);
    EXPECT_EQ(csv->blocks[0].num_rows(), static_cast<std::size_t>(f));
  }
  EXPECT_EQ(appender->stats().frames_written, 20u);
  EXPECT_EQ(appender->stats().unknown_objects, 1u);
  auto csv = ReadViconCsv(path);
  ASSERT_TRUE(csv.ok());
  auto cam0 = ExtractSubjectPoses(*csv, "cam0", pose_options);
  ASSERT_TRUE(cam0.ok()) << cam0.error().message;
  ASSERT_EQ(cam0->size(), 20u);
  for (int f = 1; f <= 20; ++f) {
    const ViconPoseSample& sample = (*cam0)[f - 1];
    EXPECT_EQ(sample.vicon_frame, 100 + f);
    if (f == 7) {
      EXPECT_FALSE(sample.vicon_from_marker.has_value());
      continue;
    }
    ASSERT_TRUE(sample.vicon_from_marker.has_value());
    EXPECT_TRUE(sample.vicon_from_marker->isApprox(MakePose(0.01 * f, f), 1e-9));
  }
}

TEST(ViconCsvAppender, WithoutFramesNoFileIsLeft) {
  test::TempDir dir;
  const fs::path path = dir / "sequence_01.csv";
  auto appender = ViconCsvAppender::Create(path, {"cam0"}, 80, {});
  ASSERT_TRUE(appender.ok());
  EXPECT_TRUE(fs::exists(path));
  ASSERT_TRUE(appender->Finish().ok());
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace lifmcr
