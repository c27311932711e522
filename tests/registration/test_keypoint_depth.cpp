// A keypoint's virtual-depth range over its support, from the measured TF
// depth map (registration/features/keypoint_depth.h; the calibration enters
// the keypoints above CalibrationOptions::max_keypoint_depth_range by their
// position only). Checked on real synthetic frames against the renderer's
// truth: frames processed with the TRUE intrinsics, so measured and true
// virtual depths compare directly.

#include "processing/camera_model.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/features/keypoint_depth.h"
#include "replay/layout.h"
#include "replay/synth/gt_images.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "tests/test_util.h"

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

}  // namespace
}  // namespace lifmcr::registration
