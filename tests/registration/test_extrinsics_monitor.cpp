// Extrinsic change detection (registration/live/extrinsics_monitor.h) on streams
// of c0_from_cx with realistic noise: what live PnP gives on the small
// synthetic rig (per-frame error median 0.42 mm / 0.026 deg, lifmcr register),
// i.e. 0.3 mm / 0.02 deg per axis, with covariances three times
// over-confident (as a solver's are when its model is not exact) and 2 % of
// triggers grossly wrong (a bad RANSAC consensus).
#include "registration/live/extrinsics_monitor.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>
#include <random>

namespace lifmcr::registration {
namespace {

using State = processing::ExtrinsicsChange::State;

constexpr double kDeg = M_PI / 180.0;

Pose MountPose() {
  Pose p = Pose::Identity();
  p.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
  p.translation() = Eigen::Vector3d(-180.0, 12.0, 25.0);
  return p;
}

// Moves `p` by `t_mm` along x and `r_deg` about y, on the left (in camera 0's frame).
Pose Knock(const Pose& p, double t_mm, double r_deg) {
  Pose knock = Pose::Identity();
  knock.linear() = Eigen::AngleAxisd(r_deg * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  knock.translation() = Eigen::Vector3d(t_mm, 0, 0);
  return knock * p;
}

class NoisyStream {
 public:
  explicit NoisyStream(unsigned seed) : rng_(seed) {}
  processing::CameraPose Next(const Pose& truth) {
    std::normal_distribution<double> t(0, 0.3), r(0, 0.02 * kDeg);
    std::uniform_real_distribution<double> u(0, 1);
    Eigen::Matrix<double, 6, 1> xi;
    xi << t(rng_), t(rng_), t(rng_), r(rng_), r(rng_), r(rng_);
    if (u(rng_) < 0.02) xi *= 20;  // a wrong consensus: 6 mm / 0.4 deg per axis
    processing::CameraPose pose;
    pose.transform = Apply(xi, truth);
    pose.covariance.setZero();
    pose.covariance.diagonal() << Eigen::Vector3d::Constant(0.1 * 0.1),
        Eigen::Vector3d::Constant(std::pow(0.007 * kDeg, 2));
    pose.method = "pnp";
    return pose;
  }

 private:
  static Pose Apply(const Eigen::Matrix<double, 6, 1>& xi, const Pose& t) {
    Pose d = Pose::Identity();
    const Eigen::Vector3d phi = xi.tail<3>();
    d.linear() = Eigen::AngleAxisd(phi.norm(), phi.normalized()).toRotationMatrix();
    d.translation() = xi.head<3>();
    return d * t;
  }
  std::mt19937 rng_;
};

TEST(ExtrinsicsMonitor, LeftDifferenceRecoversAKnock) {
  const Pose p = MountPose();
  const Eigen::Matrix<double, 6, 1> xi = LeftDifference(Knock(p, 5.0, 0.5), p);
  EXPECT_NEAR(xi[0], 5.0, 1e-9);
  EXPECT_NEAR(xi.segment<2>(1).norm(), 0.0, 1e-9);
  EXPECT_NEAR(xi[4], 0.5 * kDeg, 1e-12);
  EXPECT_NEAR(LeftDifference(p, p).norm(), 0.0, 1e-12);
}

TEST(ExtrinsicsMonitor, NoFalseAlarmOver200TriggersOfARigidRig) {
  int worst_run = 0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    ExtrinsicsMonitor monitor{ExtrinsicsMonitorOptions{}};
    NoisyStream stream(seed);
    for (int k = 0; k < 200; ++k) {
      const processing::ExtrinsicsChange c = monitor.Add("x", stream.Next(MountPose()));
      ASSERT_NE(c.state, State::kChanged) << "seed " << seed << " trigger " << k;
      worst_run = std::max(worst_run, c.departures_in_row);
      if (k >= 10) {
        EXPECT_LT(LeftDifference(c.running, MountPose()).head<3>().norm(), 0.5);
      }
    }
    EXPECT_EQ(monitor.changes("x"), 0);
  }
  std::printf("rigid rig: 20 x 200 triggers, no change flagged; longest run of departures %d\n",
              worst_run);
}

// The fused estimate (the running one, published beside each trigger's):
// the mean of the accepted triggers with the mean of their covariances over
// their number, and far nearer the mount than a single trigger.
TEST(ExtrinsicsMonitor, TheFusedEstimateCarriesItsCovarianceAndBeatsOneTrigger) {
  std::vector<double> single_mm, fused_mm;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    ExtrinsicsMonitor monitor{ExtrinsicsMonitorOptions{}};
    NoisyStream stream(seed);
    processing::ExtrinsicsChange c;
    for (int k = 0; k < 100; ++k) {
      const processing::CameraPose pose = stream.Next(MountPose());
      single_mm.push_back(LeftDifference(pose.transform, MountPose()).head<3>().norm());
      c = monitor.Add("x", pose);
    }
    ASSERT_EQ(c.state, State::kSteady);
    // Every trigger but the wrong consensuses (2 %) was fused.
    EXPECT_GE(c.running_triggers, 90);
    EXPECT_LE(c.running_triggers, 100);
    // The stream's covariance is diag(0.01 mm^2, (0.007 deg)^2) per trigger.
    EXPECT_NEAR(c.running_covariance(0, 0), 0.01 / c.running_triggers, 1e-12);
    EXPECT_NEAR(c.running_covariance(5, 5), std::pow(0.007 * kDeg, 2) / c.running_triggers, 1e-18);
    EXPECT_NEAR(c.running_covariance(0, 1), 0.0, 1e-15);
    fused_mm.push_back(LeftDifference(c.running, MountPose()).head<3>().norm());
  }
  std::sort(single_mm.begin(), single_mm.end());
  std::sort(fused_mm.begin(), fused_mm.end());
  const double single = single_mm[single_mm.size() / 2], fused = fused_mm[fused_mm.size() / 2];
  std::printf("fused after 100 triggers: median %.3f mm from the mount; one trigger %.3f mm\n",
              fused, single);
  EXPECT_LT(fused, 0.25 * single);
}

TEST(ExtrinsicsMonitor, AJumpOf5mmAndHalfADegreeIsFlaggedWithin5Triggers) {
  struct Jump {
    double t_mm, r_deg;
  };
  for (const Jump jump : {Jump{5.0, 0.5}, Jump{5.0, 0.0}, Jump{0.0, 0.5}}) {
    for (unsigned seed = 1; seed <= 10; ++seed) {
      ExtrinsicsMonitor monitor{ExtrinsicsMonitorOptions{}};
      NoisyStream stream(seed);
      const Pose before = MountPose(), after = Knock(MountPose(), jump.t_mm, jump.r_deg);
      int flagged_after = -1;
      for (int k = 0; k < 200; ++k) {
        const bool jumped = k >= 100;
        const processing::ExtrinsicsChange c = monitor.Add("x", stream.Next(jumped ? after : before));
        if (!jumped) {
          ASSERT_NE(c.state, State::kChanged) << "seed " << seed << " trigger " << k;
        } else if (c.state == State::kChanged && flagged_after < 0) {
          flagged_after = k - 100 + 1;
        }
        if (k == 199) {
          // Settled on the new mount.
          EXPECT_EQ(c.state, State::kSteady);
          EXPECT_LT(LeftDifference(c.running, after).head<3>().norm(), 0.5);
        }
      }
      EXPECT_GE(flagged_after, 1);
      EXPECT_LE(flagged_after, 5) << jump.t_mm << " mm " << jump.r_deg << " deg seed " << seed;
      EXPECT_EQ(monitor.changes("x"), 1);
    }
  }
}

TEST(ExtrinsicsMonitor, FailedRegistrationsLeaveTheStateAndOptionsAreChecked) {
  ExtrinsicsMonitor monitor{ExtrinsicsMonitorOptions{}};
  NoisyStream stream(3);
  for (int k = 0; k < 12; ++k) monitor.Add("x", stream.Next(MountPose()));
  processing::CameraPose failed;
  failed.status = "pnp: too few matches";
  failed.transform = Knock(MountPose(), 100, 10);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(monitor.Add("x", failed).departures_in_row, 0);
  EXPECT_EQ(monitor.changes("x"), 0);
  ExtrinsicsMonitorOptions o;
  o.changed_after = 0;
  EXPECT_NE(o.Check().error().message.find("changed_after"), std::string::npos);
  o = {};
  o.gate = -1;
  EXPECT_NE(o.Check().error().message.find("gate"), std::string::npos);
  o = {};
  o.settle_triggers = 1;
  EXPECT_NE(o.Check().error().message.find("settle_triggers"), std::string::npos);
  EXPECT_TRUE(ExtrinsicsMonitorOptions{}.Check());
}

}  // namespace
}  // namespace lifmcr::registration
