#pragma once
// Random right-handed poses for the Vicon source tests, and a comparison.

#include "config/frames.h"

#include <Eigen/Geometry>

#include <random>

namespace lifmcr::test {

inline Pose RandomPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::Quaterniond q(unit(rng), unit(rng), unit(rng), unit(rng));
  if (q.norm() < 1e-3) q = Eigen::Quaterniond::Identity();
  Pose pose = Pose::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 2000.0;
  return pose;
}

inline bool PosesNear(const Pose& a, const Pose& b, double tolerance) {
  return (a.linear() - b.linear()).cwiseAbs().maxCoeff() < tolerance &&
         (a.translation() - b.translation()).cwiseAbs().maxCoeff() < tolerance * 1000.0;
}

}  // namespace lifmcr::test
