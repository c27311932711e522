// A keypoint's virtual-depth range over its support, from the measured TF
// depth map (registration/features/keypoint_depth.h; the calibration enters
// the keypoints above CalibrationOptions::max_keypoint_depth_range by their
// position only). Checked on real synthetic frames against the renderer's
// truth: frames processed with the TRUE intrinsics, so measured and true
// virtual depths compare directly. And the keypoints' position on those
// frames against the truth (features.h: OpenCV's +1/4 px removed).

#include "processing/camera_model.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/detector_offset.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/features/keypoint_depth.h"
#include "replay/layout.h"
#include "replay/synth/gt_images.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "tests/test_util.h"

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace lifmcr::registration {
namespace {

namespace fs = std::filesystem;

const std::string kSerial = "40398678";

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

TEST(CalibrationKeypointDepthRange, ZeroOnAPlaneAndTheStepAcrossAnEdge) {
  const int w = 40, h = 30;
  std::vector<float> depth(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) depth[static_cast<std::size_t>(y) * w + x] = x < 20 ? 3.0f : 4.0f;
  // Wholly on one side: no range; across the edge: (4 - 3) / median.
  EXPECT_NEAR(VirtualDepthRange(depth, w, h, {8, 15}, 4), 0, 1e-7);
  const float across = VirtualDepthRange(depth, w, h, {19, 15}, 4);
  EXPECT_GT(across, 0.24f);
  EXPECT_LT(across, 0.34f);
  // Mostly empty support: unknown.
  std::fill(depth.begin(), depth.begin() + 20 * w, std::nanf(""));
  EXPECT_TRUE(std::isnan(VirtualDepthRange(depth, w, h, {8, 8}, 4)));
}

// Two `small` handheld frames from 1.8 m processed with the true intrinsics.
class CalibrationKeypointDepthOnFrames : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    Expected<synth::SynthParams> params = synth::MakePreset("small");
    ASSERT_TRUE(params);
    params->rig.cameras = 1;
    params->rig.frames = 2;
    params->rig.viewing_distance_mm = 1800;  // the marker plate whole in the TF image
    params->rig.motion = "handheld";
    Expected<synth::SynthSummary> summary = synth::WriteSyntheticDataset(dir_->path(), *params, {});
    ASSERT_TRUE(summary) << summary.error().message;
    sequence_ = new fs::path(summary->sequence_dir);
  }
  static void TearDownTestSuite() {
    delete sequence_;
    delete dir_;
  }
  static test::TempDir* dir_;
  static fs::path* sequence_;
};
test::TempDir* CalibrationKeypointDepthOnFrames::dir_ = nullptr;
fs::path* CalibrationKeypointDepthOnFrames::sequence_ = nullptr;

TEST_F(CalibrationKeypointDepthOnFrames, RangeSeparatesTheKeypointsWhoseDepthIsOff) {
  Expected<CameraCalibration> truth = ReadCameraCalibration(layout::CamerasYamlPath(*sequence_), kSerial);
  Expected<PlateLayout> plate = ReadPlateLayout(layout::CamerasYamlPath(*sequence_));
  ASSERT_TRUE(truth && plate);
  const processing::CameraModel model(truth->intrinsics);
  FrameLoaderOptions options;
  options.lambda = model.lambda();
  options.principal_point_px = truth->intrinsics.PrincipalPointPx();
  auto loader = CalibrationFrameLoader::Open(*sequence_, kSerial, {}, *plate, options);
  ASSERT_TRUE(loader) << loader.error().message;
  const double limit = 0.01;  // CalibrationOptions::max_keypoint_depth_range
  std::vector<double> kept_abs, out_abs;
  long long kept_far = 0, out_far = 0;
  for (const std::int64_t f : (*loader)->frames()) {
    Expected<CalibrationFrame> frame = (*loader)->Load(f);
    ASSERT_TRUE(frame) << frame.error().message;
    int w = 0, h = 0;
    Expected<std::vector<float>> z_mm = synth::ReadFloatTiff(layout::DepthMmPath(*sequence_, kSerial, f), &w, &h);
    ASSERT_TRUE(z_mm);
    ASSERT_EQ(w, frame->tf_width);
    auto z_at = [&](int x, int y) {
      return static_cast<double>((*z_mm)[static_cast<std::size_t>(std::clamp(y, 0, h - 1)) * w + std::clamp(x, 0, w - 1)]);
    };
    // The truth where the 3 x 3 pixels about p are one surface (1 %).
    auto true_v = [&](const Eigen::Vector2d& p) {
      const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
      double lo = 1e30, hi = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) lo = std::min(lo, z_at(x + dx, y + dy)), hi = std::max(hi, z_at(x + dx, y + dy));
      return lo > 0 && hi <= 1.01 * lo ? model.VirtualDepthOfDepth(z_at(x, y)) : std::nan("");
    };
    for (std::size_t k = 0; k < frame->features.keypoints.size(); ++k) {
      const double vt = true_v(frame->features.keypoints[k].xy_px.cast<double>());
      const double v = frame->virtual_depth[k], range = frame->virtual_depth_range[k];
      if (std::isnan(vt) || std::isnan(v) || std::isnan(range)) continue;
      const double e = std::abs(v / vt - 1);
      (range <= limit ? kept_abs : out_abs).push_back(e);
      (range <= limit ? kept_far : out_far) += e > 0.02;
    }
  }
  const double kept_far_share = static_cast<double>(kept_far) / kept_abs.size();
  const double out_far_share = static_cast<double>(out_far) / out_abs.size();
  std::printf("keypoints within %.0f %%: %zu, median |error| %.3f %%, beyond 2 %%: %.1f %%; above: %zu, %.3f %%, %.1f %%\n",
              100 * limit, kept_abs.size(), 100 * Median(kept_abs), 100 * kept_far_share, out_abs.size(),
              100 * Median(out_abs), 100 * out_far_share);
  ASSERT_GT(kept_abs.size(), 500u);
  ASSERT_GT(out_abs.size(), 100u);
  EXPECT_GT(kept_abs.size(), 0.15 * (kept_abs.size() + out_abs.size()));
  EXPECT_LT(Median(kept_abs), 0.7 * Median(out_abs));
  EXPECT_LT(kept_far_share, 0.5 * out_far_share);
}

// A keypoint against the projection of its true point, in two parts that add
// up: the detector's offset b (SIFT on the TF image and on it turned by 180
// degrees, detector_offset.h) and the TF image's shift against the renderer's all-in-focus image (the
// scene point on each TF pixel's ray; the same detector on both, so b
// cancels). Before DetectSift removed OpenCV's +1/4 px, b was +0.25 on both
// axes (bench_keypoint_position).
TEST_F(CalibrationKeypointDepthOnFrames, KeypointsSitWhereTheTruthProjects) {
  Expected<CameraCalibration> truth = ReadCameraCalibration(layout::CamerasYamlPath(*sequence_), kSerial);
  ASSERT_TRUE(truth);
  const processing::CameraModel model(truth->intrinsics);
  FrameLoaderOptions options;
  options.lambda = model.lambda();
  options.principal_point_px = truth->intrinsics.PrincipalPointPx();
  auto loader = CalibrationFrameLoader::Open(*sequence_, kSerial, {}, PlateLayout{}, options);
  ASSERT_TRUE(loader) << loader.error().message;
  std::vector<double> bx, by, sx, sy;
  for (const std::int64_t f : (*loader)->frames()) {
    Expected<CalibrationFrame> frame = (*loader)->Load(f);
    ASSERT_TRUE(frame) << frame.error().message;
    const ConstImageView tf = (*loader)->last_tf_image();
    Expected<std::vector<DetectorOffset>> offsets =
        DetectorOffsetsByTurning(tf, frame->features, options.features);
    ASSERT_TRUE(offsets) << offsets.error().message;
    for (const DetectorOffset& d : *offsets) {
      bx.push_back(d.offset_px.x());
      by.push_back(d.offset_px.y());
    }
    Features on_truth;
    const cv::Mat aif = cv::imread(synth::AllInFocusPath(*sequence_, kSerial, f).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_EQ(aif.cols, tf.width);
    ASSERT_EQ(aif.rows, tf.height);
    ASSERT_TRUE(DetectSift(ConstImageView(aif.data, aif.cols, aif.rows, aif.step, PixelFormat::kMono8),
                           options.features, &on_truth));
    std::vector<Eigen::Vector2f> truth_xy;
    for (const Keypoint& k : on_truth.keypoints) truth_xy.push_back(k.xy_px);
    const std::vector<int> match = PairByPosition(frame->features, truth_xy, on_truth, 1.0f);
    for (std::size_t i = 0; i < match.size(); ++i)
      if (match[i] >= 0) {
        const Eigen::Vector2f d = frame->features.keypoints[i].xy_px - on_truth.keypoints[match[i]].xy_px;
        sx.push_back(d.x());
        sy.push_back(d.y());
      }
  }
  const double ex = Median(bx) + Median(sx), ey = Median(by) + Median(sy);
  std::printf("detector offset (%+.3f, %+.3f) TF px over %zu pairs; TF image against the truth "
              "(%+.3f, %+.3f) over %zu; keypoints against the truth (%+.3f, %+.3f) TF px\n",
              Median(bx), Median(by), bx.size(), Median(sx), Median(sy), sx.size(), ex, ey);
  ASSERT_GT(bx.size(), 300u);
  ASSERT_GT(sx.size(), 300u);
  EXPECT_LT(std::abs(Median(bx)), 0.08);
  EXPECT_LT(std::abs(Median(by)), 0.08);
  EXPECT_LT(std::abs(ex), 0.1);
  EXPECT_LT(std::abs(ey), 0.1);
}

}  // namespace
}  // namespace lifmcr::registration
