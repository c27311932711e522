#include "replay/synth/trajectory.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>

namespace lifmcr::synth {

Pose LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, double roll_rad) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = (-Eigen::Vector3d::UnitZ()).cross(z);
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();  // looking straight down or up
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d rotation;
  rotation.col(0) = x;
  rotation.col(1) = y;
  rotation.col(2) = z;
  Pose pose = Pose::Identity();
  pose.linear() =
      rotation * Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = eye;
  return pose;
}

CameraTrajectory::CameraTrajectory(const TrajectoryParams& params) : p_(params) {
  std::mt19937_64 rng(params.seed * 0xD1B54A32D192ED03ULL + 7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto wave = [&](double amplitude, double f_min, double f_max) {
    return Wave{amplitude * (0.5 + 0.5 * unit(rng)), f_min + (f_max - f_min) * unit(rng),
                2 * M_PI * unit(rng)};
  };
  const double a = params.amplitude_scale;
  for (auto& axis : eye_)
    for (Wave& w : axis) w = wave(45.0 * a, 0.04, 0.35);
  for (auto& axis : target_)
    for (Wave& w : axis) w = wave(30.0 * a, 0.05, 0.3);
  for (Wave& w : roll_) w = wave(0.04 * a, 0.05, 0.3);
  for (int k = 0; k < 6; ++k)
    for (Wave& w : tremor_[k]) w = wave(k < 3 ? 2.5 * a : 0.004 * a, 1.0, 3.0);
  orbit_phase_ = 0.3 * (unit(rng) - 0.5);
}

double CameraTrajectory::Sum(const Wave* waves, int count, double t_s) const {
  double sum = 0.0;
  for (int k = 0; k < count; ++k)
    sum += waves[k].amplitude * std::sin(2 * M_PI * waves[k].frequency_hz * t_s + waves[k].phase);
  return sum;
}

Pose CameraTrajectory::WorldFromCam(double t_s) const {
  return RigWorldFromCam(t_s) * (t_s >= p_.knock_time_s ? p_.rig_from_cam * p_.knock
                                                        : p_.rig_from_cam);
}

Pose CameraTrajectory::RigWorldFromCam(double t_s) const {
  // Base: in front of the target (-y side), raised by the elevation, shifted
  // along x by this camera's place in the rig; all cameras look at the target.
  const Eigen::Vector3d offset(p_.lateral_offset_mm, 0, 0);
  const Eigen::Vector3d target = p_.target_mm + 0.5 * offset;
  const auto eye_at = [&](double azimuth, double elevation) -> Eigen::Vector3d {
    return p_.target_mm + offset +
           p_.distance_mm * Eigen::Vector3d(std::sin(azimuth) * std::cos(elevation),
                                            -std::cos(azimuth) * std::cos(elevation),
                                            std::sin(elevation));
  };
  const double phase = p_.duration_s > 0 ? t_s / p_.duration_s : 0.0;
  if (p_.motion == "axis") {
    // Six segments: x, y, z translation, then yaw, pitch, roll.
    const int segment = std::clamp(static_cast<int>(phase * 6), 0, 5);
    // Forth and back within the segment, starting and ending at rest so the
    // switch to the next axis has no velocity jump.
    const double local = 2 * M_PI * (phase * 6 - segment);
    const double s = std::sin(local) * (1 - std::cos(local)) / 2;
    Eigen::Vector3d eye = eye_at(0, p_.elevation_rad);
    Pose pose = LookAt(eye, target);
    const double shift = 60.0 * p_.amplitude_scale * s;
    const double angle = 0.1 * p_.amplitude_scale * s;
    if (segment < 3) {
      pose.translation()[segment] += shift;
    } else {
      const Eigen::Vector3d axis = segment == 3
                                       ? Eigen::Vector3d::UnitY()  // camera yaw: about image y
                                   : segment == 4 ? Eigen::Vector3d::UnitX()
                                                  : Eigen::Vector3d::UnitZ();
      pose.linear() = pose.linear() * Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    }
    return pose;
  }
  if (p_.motion == "orbit") {
    // Over the sequence: azimuth swept once from one side to the other,
    // elevation, distance, roll and look-at point through one cycle each.
    const double angle = 2 * M_PI * phase + orbit_phase_;
    const double scale = p_.amplitude_scale;
    const double azimuth = -0.26 * scale * std::cos(M_PI * phase);
    const double elevation = p_.elevation_rad + 0.24 * scale * std::sin(angle);
    const double distance = p_.distance_mm * (1.0 + 0.08 * scale * std::sin(angle + 1.0));
    const Eigen::Vector3d wander(30 * scale * std::sin(angle + 0.4), 30 * scale * std::cos(angle),
                                 0.0);
    const Eigen::Vector3d eye =
        target + (eye_at(azimuth, elevation) - p_.target_mm - offset) * distance / p_.distance_mm +
        0.5 * offset;
    return LookAt(eye, target + wander, 0.08 * scale * std::sin(angle + 2.0));
  }
  if (p_.motion == "circle") {
    const double azimuth = (phase - 0.5) * M_PI / 2 * p_.amplitude_scale;
    return LookAt(eye_at(azimuth, p_.elevation_rad), target);
  }
  Eigen::Vector3d eye = eye_at(0, p_.elevation_rad);
  Eigen::Vector3d look = target;
  double roll = Sum(roll_, 2, t_s);
  for (int k = 0; k < 3; ++k) eye[k] += Sum(eye_[k], 3, t_s);
  for (int k = 0; k < 3; ++k) look[k] += Sum(target_[k], 2, t_s);
  if (p_.motion == "handheld") {
    for (int k = 0; k < 3; ++k) eye[k] += Sum(tremor_[k], 2, t_s);
    roll += Sum(tremor_[3], 2, t_s);
    Pose pose = LookAt(eye, look, roll);
    const Eigen::Matrix3d shake =
        (Eigen::AngleAxisd(Sum(tremor_[4], 2, t_s), Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(Sum(tremor_[5], 2, t_s), Eigen::Vector3d::UnitY()))
            .toRotationMatrix();
    pose.linear() = pose.linear() * shake;
    return pose;
  }
  return LookAt(eye, look, roll);
}

}  // namespace lifmcr::synth
