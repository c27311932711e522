#include "tests/registration/random_geometry.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

namespace lifmcr::test {

Pose RandomPose(std::mt19937_64& rng, double translation_mm) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-translation_mm, translation_mm);
  // A normalised 4D Gaussian is a uniformly random unit quaternion.
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  Pose pose = Pose::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
  return pose;
}

double PoseErrorMahalanobis(const Pose& truth, const Pose& estimate,
                            const Eigen::Matrix<double, 6, 6>& covariance) {
  Eigen::Matrix<double, 6, 1> delta;
  delta.head<3>() = truth.translation() - estimate.translation();
  const Eigen::AngleAxisd rotation(truth.linear() * estimate.linear().transpose());
  delta.tail<3>() = rotation.angle() * rotation.axis();
  return delta.dot(covariance.ldlt().solve(delta));
}

processing::CameraIntrinsics SmallCameraIntrinsics() {
  processing::CameraIntrinsics k;
  k.main_focal_length_mm = 25.0;
  k.mla_to_main_lens_mm = 24.80;
  k.mla_to_sensor_mm = 0.2042;
  k.pixel_size_mm = 0.0055;
  k.width_px = 1024;
  k.height_px = 768;
  return k;
}

PnpProblem MakePnpProblem(std::mt19937_64& rng, const processing::CameraModel& camera, int count,
                          double outlier_fraction, double sigma_tf_px, double sigma_v,
                          double v_min, double v_max) {
  const double tf_w = camera.intrinsics().width_px / 2.0, tf_h = camera.intrinsics().height_px / 2.0;
  std::uniform_real_distribution<double> u_tf(0, tf_w - 1), w_tf(0, tf_h - 1), v_dist(v_min, v_max);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> noise_px(0, sigma_tf_px > 0 ? sigma_tf_px : 1e-300);
  std::normal_distribution<double> noise_v(0, sigma_v > 0 ? sigma_v : 1e-300);
  PnpProblem problem;
  problem.cam_from_world = RandomPose(rng, 500);
  const Pose world_from_cam = problem.cam_from_world.inverse();
  for (int i = 0; i < count; ++i) {
    Eigen::Vector2d tf(u_tf(rng), w_tf(rng));
    double v = v_dist(rng);
    const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(tf);
    const Eigen::Vector3d p_in_cam = camera.BackProject({raw.x(), raw.y(), v});
    problem.points_in_cam.push_back(p_in_cam);
    problem.points_in_world.push_back(world_from_cam * p_in_cam);
    const bool outlier = unit(rng) < outlier_fraction;
    if (outlier) {
      tf = Eigen::Vector2d(u_tf(rng), w_tf(rng));
      v = v_dist(rng);
    } else {
      if (sigma_tf_px > 0) tf += Eigen::Vector2d(noise_px(rng), noise_px(rng));
      if (sigma_v > 0) v += noise_v(rng);
    }
    problem.tf_px.push_back(tf);
    problem.virtual_depth.push_back(v);
    problem.is_outlier.push_back(outlier);
  }
  return problem;
}

}  // namespace lifmcr::test
