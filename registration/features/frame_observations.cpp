#include "registration/features/frame_observations.h"

#include "registration/features/calibration_frames.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/layout.h"
#include "replay/synth/synth_writer.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <cmath>
#include <limits>

namespace lifmcr::registration {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

class RawObserver final : public FrameObserver {
 public:
  RawObserver(std::unique_ptr<CalibrationFrameLoader> loader, const processing::CameraModel& camera)
      : loader_(std::move(loader)), camera_(camera) {}
  const std::vector<std::int64_t>& frames() const override { return loader_->frames(); }
  Expected<FrameObservations> Observe(std::int64_t frame) override {
    const auto start = std::chrono::steady_clock::now();
    Expected<CalibrationFrame> loaded = loader_->Load(frame);
    if (!loaded) return loaded.error();
    FrameObservations out;
    out.frame = frame;
    out.features = std::move(loaded->features);
    out.virtual_depth.assign(loaded->virtual_depth.begin(), loaded->virtual_depth.end());
    CompleteObservations(camera_, &out);
    out.seconds = SecondsSince(start);
    return out;
  }

 private:
  std::unique_ptr<CalibrationFrameLoader> loader_;
  processing::CameraModel camera_;
};

// Bilinear depth at a sub-pixel keypoint (the ground truth is exact, so a
// nearest-pixel sample would add up to half a pixel's depth gradient);
// the nearest pixel where a neighbour has no depth.
double SampleDepth(const cv::Mat& depth, const Eigen::Vector2d& xy) {
  const int x0 = static_cast<int>(std::floor(xy.x())), y0 = static_cast<int>(std::floor(xy.y()));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= depth.cols || y0 + 1 >= depth.rows) {
    const int u = static_cast<int>(std::lround(xy.x())), w = static_cast<int>(std::lround(xy.y()));
    if (u < 0 || w < 0 || u >= depth.cols || w >= depth.rows)
      return std::numeric_limits<double>::quiet_NaN();
    return depth.at<float>(w, u);
  }
  const double fx = xy.x() - x0, fy = xy.y() - y0;
  const double d00 = depth.at<float>(y0, x0), d10 = depth.at<float>(y0, x0 + 1);
  const double d01 = depth.at<float>(y0 + 1, x0), d11 = depth.at<float>(y0 + 1, x0 + 1);
  const double bilinear =
      (d00 * (1 - fx) + d10 * fx) * (1 - fy) + (d01 * (1 - fx) + d11 * fx) * fy;
  if (std::isfinite(bilinear)) return bilinear;
  return depth.at<float>(static_cast<int>(std::lround(xy.y())) < depth.rows ? static_cast<int>(std::lround(xy.y())) : y0,
                         static_cast<int>(std::lround(xy.x())) < depth.cols ? static_cast<int>(std::lround(xy.x())) : x0);
}

class GroundTruthObserver final : public FrameObserver {
 public:
  GroundTruthObserver(std::filesystem::path sequence_dir, std::string serial,
                      const processing::CameraModel& camera, const FeatureOptions& features,
                      std::vector<std::int64_t> frames)
      : sequence_dir_(std::move(sequence_dir)),
        serial_(std::move(serial)),
        camera_(camera),
        features_(features),
        frames_(std::move(frames)) {}
  const std::vector<std::int64_t>& frames() const override { return frames_; }
  Expected<FrameObservations> Observe(std::int64_t frame) override {
    const auto start = std::chrono::steady_clock::now();
    const std::filesystem::path image_path = synth::AllInFocusPath(sequence_dir_, serial_, frame);
    const std::filesystem::path depth_path = layout::DepthMmPath(sequence_dir_, serial_, frame);
    const cv::Mat image = cv::imread(image_path.string(), cv::IMREAD_COLOR);
    if (image.empty()) return Error{image_path.string() + ": cannot read the all-in-focus image"};
    const cv::Mat depth = cv::imread(depth_path.string(), cv::IMREAD_UNCHANGED);
    if (depth.empty() || depth.type() != CV_32FC1)
      return Error{depth_path.string() + ": expected a float32 TIFF of camera z (mm)"};
    if (depth.size() != image.size())
      return Error{depth_path.string() + ": " + std::to_string(depth.cols) + "x" +
                   std::to_string(depth.rows) + " does not match the all-in-focus image's " +
                   std::to_string(image.cols) + "x" + std::to_string(image.rows)};
    FrameObservations out;
    out.frame = frame;
    const ConstImageView view(image.data, image.cols, image.rows, image.step[0],
                              PixelFormat::kBgr8);
    if (Status s = DetectSift(view, features_, &out.features); !s)
      return Error{image_path.string() + ": " + s.error().message};
    out.virtual_depth.assign(out.features.keypoints.size(),
                             std::numeric_limits<double>::quiet_NaN());
    for (std::size_t i = 0; i < out.features.keypoints.size(); ++i) {
      const double z = SampleDepth(depth, out.features.keypoints[i].xy_px.cast<double>());
      if (std::isfinite(z) && z > camera_.intrinsics().main_focal_length_mm)
        out.virtual_depth[i] = camera_.VirtualDepthOfDepth(z);
    }
    CompleteObservations(camera_, &out);
    out.seconds = SecondsSince(start);
    return out;
  }

 private:
  std::filesystem::path sequence_dir_;
  std::string serial_;
  processing::CameraModel camera_;
  FeatureOptions features_;
  std::vector<std::int64_t> frames_;
};

}  // namespace

void CompleteObservations(const processing::CameraModel& camera, FrameObservations* frame) {
  const std::size_t n = frame->features.keypoints.size();
  frame->tf_px.resize(n);
  frame->virtual_depth.resize(n, std::numeric_limits<double>::quiet_NaN());
  frame->p_in_cam.assign(n, Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (std::size_t i = 0; i < n; ++i) {
    frame->tf_px[i] = frame->features.keypoints[i].xy_px.cast<double>();
    const double v = frame->virtual_depth[i];
    // v <= 1 images in front of the sensor (no depth from a Galilean camera).
    if (!std::isfinite(v) || v <= 1.0) {
      frame->virtual_depth[i] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(frame->tf_px[i]);
    frame->p_in_cam[i] = camera.BackProject({raw.x(), raw.y(), v});
  }
}

Expected<std::unique_ptr<FrameObserver>> FrameObserver::Open(
    ObservationSource source, const std::filesystem::path& sequence_dir, const std::string& serial,
    const processing::CameraModel& camera, const std::filesystem::path& plate_yaml,
    const FeatureOptions& features) {
  if (source == ObservationSource::kGroundTruth) {
    // The frames are those of the ground-truth pose file.
    std::vector<std::int64_t> frames;
    std::error_code ec;
    for (std::int64_t frame = 0;; ++frame) {
      if (!std::filesystem::exists(layout::DepthMmPath(sequence_dir, serial, frame), ec)) break;
      frames.push_back(frame);
    }
    if (frames.empty())
      return Error{layout::DepthMmPath(sequence_dir, serial, 0).string() +
                   ": no ground-truth depth (a sequence of lifmcr synth is needed)"};
    return std::unique_ptr<FrameObserver>(
        new GroundTruthObserver(sequence_dir, serial, camera, features, std::move(frames)));
  }
  PlateLayout plate;
  if (!plate_yaml.empty()) {
    Expected<PlateLayout> read = ReadPlateLayout(plate_yaml);
    if (read) plate = *read;  // no plate section: no markers to find
  }
  FrameLoaderOptions options;
  options.lambda = camera.lambda();
  options.features = features;
  Expected<std::unique_ptr<CalibrationFrameLoader>> loader =
      CalibrationFrameLoader::Open(sequence_dir, serial, {}, plate, options);
  if (!loader) return loader.error();
  return std::unique_ptr<FrameObserver>(new RawObserver(std::move(*loader), camera));
}

}  // namespace lifmcr::registration
