#pragma once
// Extrinsic change detection for rigidly mounted cameras: camera X's
// c0_from_cx should not change while the rig records, so a run of triggers
// whose estimate departs from the running estimate by more than both
// uncertainties allow means the camera moved on its mount (was knocked).
//
// Per camera, for each c0_from_cx T_k (status ok) with covariance S_k (left
// perturbation, (t mm, r rad), processing/registration_stage.h):
//   residual   xi_k = log(T_k T_run^-1) ~ (t_k - dR t_run, rotvec(dR)),
//              dR = R_k R_run^T (small angles),
//   departure  d_k = xi_k^T (S_k + S_run + S_floor)^-1 xi_k, chi-square with
//              6 dof when the covariances are right; S_floor = diag(sigma_floor^2)
//              keeps over-confident per-frame covariances from raising alarms,
//   running    T_run: the mean in the tangent space (at the first accepted
//              pose) of the accepted poses; S_run = mean(S_k) / n + (its
//              own floor, none). Both are in every verdict (running,
//              running_covariance, running_triggers): the fused estimate of
//              a rigid mount, published beside the per-trigger one. S_run
//              takes the triggers' errors as independent; tracked triggers
//              that share their tracks' templates are not, so it is a lower
//              bound.
// States: kSettling until settle_triggers poses were accepted (every pose is
// accepted, the gate not yet applied; at the end the estimate is refitted
// without the settling poses beyond the gate, so one wrong consensus does not
// bias it); then kSteady when d_k <= gate, else
// kDeparting (not accepted) and, after changed_after triggers in a row,
// kChanged: the estimate restarts from the departed poses (the new mount) and
// reports kChanged until it has settled again. A failed registration leaves
// the state as it was.

#include "config/frames.h"
#include "processing/registration_stage.h"

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct ExtrinsicsMonitorOptions {
  int settle_triggers = 10;   // poses accepted before the gate applies (>= 2)
  int changed_after = 3;      // departures in a row that flag a change (>= 1)
  double gate = 22.46;        // on the departure: chi-square 6 dof, p = 0.001 (> 0)
  double sigma_floor_mm = 0.5;    // added to each translation variance (>= 0)
  double sigma_floor_deg = 0.05;  // added to each rotation variance (>= 0)
  Status Check() const;
};

class ExtrinsicsMonitor {
 public:
  explicit ExtrinsicsMonitor(const ExtrinsicsMonitorOptions& options) : options_(options) {}
  // The verdict on camera `serial`'s c0_from_cx of trigger `trigger_index`.
  processing::ExtrinsicsChange Add(const std::string& serial, const processing::CameraPose& c0_from_cx);
  // How many changes were flagged for `serial` so far.
  int changes(const std::string& serial) const;

 private:
  struct Track {
    bool has_anchor = false;
    Pose anchor = Pose::Identity();
    Eigen::Matrix<double, 6, 1> sum_xi = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Matrix<double, 6, 6> sum_cov = Eigen::Matrix<double, 6, 6>::Zero();
    int accepted = 0;
    bool changed = false;  // kChanged until settled again
    int changes = 0;
    std::vector<processing::CameraPose> departed;  // the current run of departures
    std::vector<processing::CameraPose> settling;  // accepted while settling
    processing::ExtrinsicsChange last;
    Pose Running() const;
    void Accept(const processing::CameraPose& pose);
    // Sum of the accepted covariances over n^2: the running estimate's.
    Eigen::Matrix<double, 6, 6> RunningCovariance() const;
  };
  double Departure(const Track& track, const processing::CameraPose& pose) const;
  void RefitWithoutOutliers(Track* track) const;
  ExtrinsicsMonitorOptions options_;
  std::map<std::string, Track> tracks_;
};

// The relate step: c0_from_cx of one trigger from the reference camera's and
// camera X's poses (processing::ComposeExtrinsics) and, with MonitorChanges,
// the change detection's verdict on it. The in-process pipeline's
// (MapLocalizerStage::Relate) and `lifmcr relate`'s (poses from other
// hosts) are this one, so both publish the same message for the same poses.
// One thread; per camera in trigger order for the change detection.
class ExtrinsicsRelater {
 public:
  // Rigidly mounted cameras: every c0_from_cx goes through change detection.
  // Before the first Relate.
  void MonitorChanges(const ExtrinsicsMonitorOptions& options) { monitor_.emplace(options); }
  processing::CameraPose Relate(const std::string& serial, const processing::CameraPose& w0_from_c0,
                                const processing::CameraPose& w0_from_cx);
  bool monitoring() const { return monitor_.has_value(); }

 private:
  std::optional<ExtrinsicsMonitor> monitor_;
};

// xi = log(a b^-1) to first order: (t_a - dR t_b, rotvec(dR)), dR = R_a R_b^T.
Eigen::Matrix<double, 6, 1> LeftDifference(const Pose& a, const Pose& b);

}  // namespace lifmcr::registration
