#include "registration/frame_registration.h"

#include "registration/tf_projection.h"

#include <chrono>
#include <cmath>
#include <cstdio>

namespace lifmcr::registration {

std::string_view ToString(RegistrationMethod method) {
  return method == RegistrationMethod::kPnp ? "pnp" : "ransac";
}

std::optional<RegistrationMethod> ParseRegistrationMethod(std::string_view name) {
  if (name == "pnp") return RegistrationMethod::kPnp;
  if (name == "ransac") return RegistrationMethod::kRansac3d;
  return std::nullopt;
}

MapIndex MapIndex::Of(const ReferenceMap& map) {
  MapIndex index;
  index.points_in_w0.reserve(map.points.size());
  index.descriptors.reserve(map.points.size() * kDescriptorSize);
  for (const MapPoint& point : map.points) {
    if (point.descriptor.size() != static_cast<std::size_t>(kDescriptorSize)) continue;
    index.points_in_w0.push_back(point.p_in_w0_mm);
    index.descriptors.insert(index.descriptors.end(), point.descriptor.begin(),
                             point.descriptor.end());
  }
  return index;
}

Status FrameRegistrationOptions::Check() const {
  if (Status s = match.Check(); !s) return s;
  if (Status s = pnp.Check(); !s) return s;
  if (Status s = rigid.Check(); !s) return s;
  if (!(sigma_v_relative > 0) || !std::isfinite(sigma_v_relative))
    return Error{"registration options: sigma_v_relative: expected a finite number > 0"};
  if (!(sigma_tf_px > 0) || !std::isfinite(sigma_tf_px))
    return Error{"registration options: sigma_tf_px: expected a finite number > 0"};
  return Status::Ok();
}

std::string FrameRegistration::BriefReport(RegistrationMethod method) const {
  char line[256];
  std::snprintf(line, sizeof line, "%s %s: %zu inliers of %zu matches, rmse %.3f px, %.1f ms",
                std::string(ToString(method)).c_str(), status.c_str(), inliers, matches, rmse_px,
                1e3 * seconds);
  return line;
}

FrameRegistration RegisterFrame(const MapIndex& map, const processing::CameraModel& camera,
                                const FrameObservations& frame, RegistrationMethod method,
                                const FrameRegistrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  FrameRegistration result;
  const auto finish = [&](std::string status) {
    result.status = std::move(status);
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  };
  const std::vector<Match> matches =
      MatchDescriptors(frame.features.descriptors.data(), frame.features.size(),
                       map.descriptors.data(), map.size(), options.match);
  result.matches = matches.size();

  if (method == RegistrationMethod::kPnp) {
    std::vector<Eigen::Vector3d> points;
    std::vector<Eigen::Vector2d> tf;
    std::vector<double> v;
    for (const Match& m : matches) {
      points.push_back(map.points_in_w0[m.train]);
      tf.push_back(frame.tf_px[m.query]);
      v.push_back(frame.virtual_depth[m.query]);
    }
    const PnpResult pnp = EstimatePlenopticPnp(camera, {points, tf, v}, options.pnp);
    result.inliers = pnp.num_inliers;
    result.rmse_px = pnp.rmse_px;
    if (!pnp.success) return finish(pnp.status);
    result.w0_from_cam = Inverse(PoseWithCovariance{pnp.cam_from_world, pnp.covariance});
    for (std::size_t i = 0; i < matches.size() && i < pnp.inlier_mask.size(); ++i) {
      if (!pnp.inlier_mask[i]) continue;
      result.inlier_points.push_back(matches[i].train);
      result.inlier_tf_px.push_back(tf[i]);
    }
    result.success = true;
    return finish("ok");
  }

  std::vector<Eigen::Vector3d> src, dst;
  std::vector<Eigen::Matrix3d> covariance;
  std::vector<Eigen::Vector2d> tf;
  for (const Match& m : matches) {
    const Eigen::Vector3d& p = frame.p_in_cam[m.query];
    if (!p.allFinite()) continue;
    src.push_back(p);
    dst.push_back(map.points_in_w0[m.train]);
    covariance.push_back(PlenopticPointCovariance(
        camera, p, options.sigma_v_relative * frame.virtual_depth[m.query], options.sigma_tf_px));
    tf.push_back(frame.tf_px[m.query]);
  }
  const Rigid3dResult rigid = EstimateRigid3d({src, covariance, dst}, options.rigid);
  result.inliers = rigid.num_inliers;
  if (!rigid.success) return finish(rigid.status);
  result.w0_from_cam = {rigid.dst_from_src, rigid.covariance};
  // Reprojection RMS of the inliers, comparable with PnP's.
  const TfProjection projection = TfProjection::Of(camera);
  const Pose cam_from_w0 = rigid.dst_from_src.inverse();
  double sum = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    if (!rigid.inlier_mask[i]) continue;
    const double e2 = projection.SquaredError(cam_from_w0 * dst[i], tf[i]);
    if (!std::isfinite(e2)) continue;
    sum += e2;
    ++count;
  }
  result.rmse_px = count ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  result.success = true;
  return finish("ok");
}

}  // namespace lifmcr::registration
