#include "registration/calibration/truth_substitution.h"

#include "processing/camera_model.h"
#include "registration/calibration/calibration_gates.h"
#include "registration/calibration/plenoptic_projection.h"
#include "replay/layout.h"
#include "replay/synth/gt_images.h"
#include "replay/synth/synth_writer.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <limits>
#include <map>

namespace lifmcr::registration {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

Expected<TruthSubstitution> ParseTruthSubstitution(std::string_view list) {
  TruthSubstitution t;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t end = std::min(list.find(',', start), list.size());
    const std::string_view name = list.substr(start, end - start);
    if (name == "keypoint-depth") t.keypoint_depth = true;
    else if (name == "keypoints") t.keypoints = true;
    else if (name == "corners") t.corners = true;
    else if (name == "corner-depth") t.corner_depth = true;
    else if (name == "no-corner-depth") t.no_corner_depth = true;
    else
      return Error{"--substitute-truth: '" + std::string(name) +
                   "' is not one of keypoint-depth, keypoints, corners, corner-depth, "
                   "no-corner-depth"};
    start = end + 1;
  }
  if (t.keypoint_depth && t.keypoints)
    return Error{"--substitute-truth: keypoints already holds keypoint-depth; name one"};
  if (int(t.corners) + int(t.corner_depth) + int(t.no_corner_depth) > 1)
    return Error{"--substitute-truth: name one of corners, corner-depth, no-corner-depth"};
  return t;
}

Expected<std::string> SubstituteTruth(const TruthSubstitution& what,
                                      const std::filesystem::path& seq, const std::string& serial,
                                      double lambda0, const Eigen::Vector2d& c0_px,
                                      const FeatureOptions& features,
                                      std::vector<CalibrationFrame>* frames) {
  Expected<SequenceTruth> sequence_truth = ReadSequenceTruth(seq, serial);
  if (!sequence_truth) return sequence_truth.error();
  const CameraCalibration* truth = &sequence_truth->camera;
  const std::map<std::int64_t, Pose>& cam_from_world = sequence_truth->cam_from_world;
  const processing::CameraModel model(truth->intrinsics);
  const IntrinsicsVector k = ToVector(truth->intrinsics);
  const ProcessedGeometry geometry{model.lambda(), lambda0, truth->intrinsics.PrincipalPointPx(),
                                   c0_px};
  const double f_l = truth->intrinsics.main_focal_length_mm;
  long long keypoints = 0, keypoints_without = 0, corners = 0;
  for (CalibrationFrame& frame : *frames) {
    const auto pose = cam_from_world.find(frame.frame);
    if (pose == cam_from_world.end())
      return Error{layout::PosesCsvPath(seq, serial).string() + ": no pose of frame " +
                   std::to_string(frame.frame)};
    int w = 0, h = 0;
    Expected<std::vector<float>> depth =
        synth::ReadFloatTiff(layout::DepthMmPath(seq, serial, frame.frame), &w, &h);
    if (!depth) return depth.error();
    if (what.keypoint_depth) {
      for (std::size_t i = 0; i < frame.features.keypoints.size(); ++i) {
        const double v = TrueOfProcessedOnSurface(geometry, model, *depth, w, h,
                                                  VirtualOfTf(frame.features.keypoints[i].xy_px.cast<double>()))
                             .v;
        frame.virtual_depth[i] = static_cast<float>(std::isnan(v) ? kNaN : geometry.ProcessedDepth(v));
        ++(std::isnan(v) ? keypoints_without : keypoints);
      }
    }
    if (what.keypoints) {
      const std::filesystem::path path = synth::AllInFocusPath(seq, serial, frame.frame);
      const cv::Mat image = cv::imread(path.string(), cv::IMREAD_COLOR);
      if (image.empty()) return Error{path.string() + ": cannot read the all-in-focus image"};
      if (image.cols != w || image.rows != h)
        return Error{path.string() + ": not the size of the ground-truth depth map"};
      Features found;
      const ConstImageView view(image.data, image.cols, image.rows, image.step[0],
                                PixelFormat::kBgr8);
      if (Status s = DetectSift(view, features, &found); !s)
        return Error{path.string() + ": " + s.error().message};
      Features kept;
      frame.virtual_depth.clear();
      frame.virtual_depth_range.clear();
      frame.rgb.clear();
      for (int i = 0; i < found.size(); ++i) {
        const Eigen::Vector2d tf = found.keypoints[i].xy_px.cast<double>();
        const double z = SurfaceDepthMm(*depth, w, h, tf);
        if (!(z > f_l)) {
          ++keypoints_without;
          continue;
        }
        const double v = model.VirtualDepthOfDepth(z);
        Keypoint kp = found.keypoints[i];
        kp.xy_px = TfOfVirtual(geometry.ProcessedOfTrue(VirtualOfTf(tf), v)).cast<float>();
        kept.keypoints.push_back(kp);
        kept.descriptors.insert(kept.descriptors.end(), found.Descriptor(i),
                                found.Descriptor(i) + kDescriptorSize);
        frame.virtual_depth.push_back(static_cast<float>(geometry.ProcessedDepth(v)));
        frame.virtual_depth_range.push_back(0.0f);  // one surface: no range over the support
        const cv::Vec3b bgr = image.at<cv::Vec3b>(static_cast<int>(std::lround(tf.y())),
                                                  static_cast<int>(std::lround(tf.x())));
        frame.rgb.push_back({bgr[2], bgr[1], bgr[0]});
        ++keypoints;
      }
      frame.features = std::move(kept);
    }
    if (what.corners || what.corner_depth || what.no_corner_depth) {
      frame.corner_virtual_depth.resize(frame.corners.size(), static_cast<float>(kNaN));
      for (std::size_t n = 0; n < frame.corners.size(); ++n) {
        PlateCorner& corner = frame.corners[n];
        if (what.no_corner_depth) {
          frame.corner_virtual_depth[n] = static_cast<float>(kNaN);
          ++corners;
          continue;
        }
        const Eigen::Vector3d p = pose->second * corner.p_in_w_mm;
        double x_v[3];
        if (!ProjectToVirtual(k.data(), truth->intrinsics.pixel_size_mm, p.data(), x_v)) continue;
        frame.corner_virtual_depth[n] = static_cast<float>(geometry.ProcessedDepth(x_v[2]));
        if (what.corners)
          corner.tf_px = TfOfVirtual(geometry.ProcessedOfTrue({x_v[0], x_v[1]}, x_v[2]));
        ++corners;
      }
    }
  }
  std::string text = "substituted by the truth:";
  if (what.keypoint_depth || what.keypoints)
    text += " " + std::to_string(keypoints) + (what.keypoints ? " keypoints" : " keypoint depths") +
            " (" + std::to_string(keypoints_without) + " without a true depth)";
  if (what.corners || what.corner_depth || what.no_corner_depth)
    text += " " + std::to_string(corners) +
            (what.corners ? " plate corners" : what.corner_depth ? " plate corner depths"
                                                                 : " plate corner depths removed");
  return text;
}

}  // namespace lifmcr::registration
