#include "registration/calibration/rig_truth_per_frame.h"

#include "registration/estimators/pose_covariance.h"

#include <algorithm>
#include <cstdio>
#include <limits>

namespace lifmcr::registration {
namespace {

std::string PerFrameFormat(const char* fmt, auto... args) {
  char buffer[1024];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

// The middle value; of an even count the mean of the middle two (as
// `lifmcr register` reports its medians).
double MedianOf(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The 95 % quantile of chi-square(6).
constexpr double kChi2Dof6Quantile95 = 12.592;

double MaxOf(const std::vector<double>& v) {
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : *std::max_element(v.begin(), v.end());
}

std::map<std::int64_t, Pose> ByFrame(const std::vector<FramePose>& poses) {
  std::map<std::int64_t, Pose> out;
  for (const FramePose& p : poses) out[p.frame] = p.world_from_cam;
  return out;
}

std::string Cell(double mm, double deg) {
  return std::isnan(mm) ? std::string("—") : PerFrameFormat("%.3f mm / %.4f°", mm, deg);
}

}  // namespace

Expected<RigPerFrameTruth> CompareNonRigidWithTruth(
    const RigCalibrationResult& result, const std::vector<CameraCalibration>& truth,
    const std::vector<std::map<std::int64_t, Pose>>& c0_from_cx_truth,
    const std::vector<std::vector<FramePose>>& registered_alone) {
  const std::size_t n = result.cameras.size();
  if (truth.size() != n || c0_from_cx_truth.size() != n)
    return Error{PerFrameFormat("rig truth per frame: %zu cameras calibrated, %zu true "
                                "intrinsics, %zu true trajectories",
                                n, truth.size(), c0_from_cx_truth.size())};
  RigPerFrameTruth out;
  for (std::size_t c = 0; c < n; ++c) {
    const RigCameraResult& rc = result.cameras[c];
    const IntrinsicsVector e = ToVector(rc.calibration.intrinsics);
    const IntrinsicsVector t = ToVector(truth[c].intrinsics);
    RigPerFrameTruth::Camera k;
    k.serial = rc.serial;
    k.f_l_rel = e[0] / t[0] - 1;
    k.b_l0_rel = e[1] / t[1] - 1;
    k.b_rel = e[2] / t[2] - 1;
    k.principal_point_px = std::hypot(e[3] - t[3], e[4] - t[4]);
    {
      const auto joint = ByFrame(c == 0 ? result.trajectory : rc.per_trigger);
      const auto start = ByFrame(c == 0 ? result.camera0.poses : rc.per_trigger_initial);
      const auto passed = ByFrame(c == 0 ? result.camera0.poses : rc.registered);
      const auto alone = c < registered_alone.size() ? ByFrame(registered_alone[c])
                                                     : std::map<std::int64_t, Pose>{};
      std::vector<double> jmm, jdeg, amm, adeg, pmm, pdeg;
      // The joint covariance per trigger ([rotation rad, translation mm],
      // rig_calibration.h) in pose_covariance.h's order (t, r).
      std::map<std::int64_t, Covariance6> covariance;
      if (c > 0 && result.covariance_computed)
        for (std::size_t i = 0; i < rc.per_trigger.size() && i < rc.per_trigger_covariance.size();
             ++i) {
          const Eigen::Matrix<double, 6, 6>& rt = rc.per_trigger_covariance[i];
          Covariance6 tr;
          tr << rt.bottomRightCorner<3, 3>(), rt.bottomLeftCorner<3, 3>(),
              rt.topRightCorner<3, 3>(), rt.topLeftCorner<3, 3>();
          covariance[rc.per_trigger[i].frame] = tr;
        }
      const auto w0_from_c0 = ByFrame(result.trajectory);
      for (const FramePose& trigger : result.trajectory) {
        const auto truth_pose = c0_from_cx_truth[c].find(trigger.frame);
        if (truth_pose == c0_from_cx_truth[c].end()) continue;
        RigPerFrameTruth::Row row;
        row.frame = trigger.frame;
        if (const auto p = joint.find(trigger.frame); p != joint.end()) {
          row.joint_mm = TranslationDifference(p->second, truth_pose->second);
          row.joint_deg = RotationDifferenceDeg(p->second, truth_pose->second);
          jmm.push_back(row.joint_mm);
          jdeg.push_back(row.joint_deg);
          const auto true_w0_from_c0 = c0_from_cx_truth[0].find(trigger.frame);
          if (c > 0 && true_w0_from_c0 != c0_from_cx_truth[0].end()) {
            const Pose estimate = w0_from_c0.at(trigger.frame) * p->second;
            const Pose truth_w0 = true_w0_from_c0->second * truth_pose->second;
            row.plate_mm = TranslationDifference(estimate, truth_w0);
            row.plate_deg = RotationDifferenceDeg(estimate, truth_w0);
            pmm.push_back(row.plate_mm);
            pdeg.push_back(row.plate_deg);
          }
          if (const auto s = covariance.find(trigger.frame);
              s != covariance.end() && !s->second.isZero()) {
            row.chi2 = SquaredMahalanobis({p->second, s->second}, truth_pose->second);
            ++k.with_covariance;
            if (row.chi2 <= kChi2Dof6Quantile95) ++k.within_chi2_95;
          }
        }
        if (const auto p = start.find(trigger.frame); p != start.end()) {
          row.start_mm = TranslationDifference(p->second, truth_pose->second);
          row.start_deg = RotationDifferenceDeg(p->second, truth_pose->second);
          row.start_passed = passed.count(trigger.frame) > 0;
        }
        if (const auto p = alone.find(trigger.frame); p != alone.end()) {
          row.alone_mm = TranslationDifference(p->second, truth_pose->second);
          row.alone_deg = RotationDifferenceDeg(p->second, truth_pose->second);
          amm.push_back(row.alone_mm);
          adeg.push_back(row.alone_deg);
        }
        k.rows.push_back(row);
      }
      k.placed = static_cast<int>(jmm.size());
      k.alone_registered = static_cast<int>(amm.size());
      k.joint_max_mm = MaxOf(jmm);
      k.joint_max_deg = MaxOf(jdeg);
      k.joint_median_mm = MedianOf(jmm);
      k.joint_median_deg = MedianOf(jdeg);
      k.alone_median_mm = MedianOf(amm);
      k.alone_median_deg = MedianOf(adeg);
      k.plate_median_mm = MedianOf(pmm);
      k.plate_median_deg = MedianOf(pdeg);
    }
    out.cameras.push_back(std::move(k));
  }
  return out;
}

std::string RigPerFrameTruth::Report() const {
  std::string text;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const Camera& k = cameras[c];
    text += PerFrameFormat("camera %zu (%s) vs truth: f_L %+.3f %%, b_L0 %+.3f %%, B %+.3f %%, "
                           "principal point %.2f px",
                           c, k.serial.c_str(), 100 * k.f_l_rel, 100 * k.b_l0_rel, 100 * k.b_rel,
                           k.principal_point_px);
    if (c == 0)
      text += PerFrameFormat("; w0_from_c0 (the plate frame) per frame, joint: median %s, worst "
                             "%.3f mm / %.4f°",
                             Cell(k.joint_median_mm, k.joint_median_deg).c_str(), k.joint_max_mm,
                             k.joint_max_deg);
    else
      text += PerFrameFormat(
          "; c0_from_cx per frame, joint (%d of %zu frames placed): median %s, worst %.3f mm / "
          "%.4f°; registered alone against camera 0's map (%d frames): median %s",
          k.placed, k.rows.size(), Cell(k.joint_median_mm, k.joint_median_deg).c_str(),
          k.joint_max_mm, k.joint_max_deg, k.alone_registered,
          Cell(k.alone_median_mm, k.alone_median_deg).c_str());
    if (c > 0)
      text += PerFrameFormat("; joint w0_from_cx (the plate frame, camera 0's own error left "
                             "out): median %s",
                             Cell(k.plate_median_mm, k.plate_median_deg).c_str());
    if (c > 0 && k.with_covariance > 0)
      text += PerFrameFormat("; %d of %d frames (%.0f %%) within the 95 %% chi-square(6) bound "
                             "of their joint covariance",
                             k.within_chi2_95, k.with_covariance,
                             100.0 * k.within_chi2_95 / k.with_covariance);
    text += "\n";
  }
  text += "| camera | frame | joint | joint in the plate frame (X: w0_from_cx) | joint chi2 | start (camera 0: calibrated alone; X: PnP against the map of the cameras before it) | alone (camera 0's map) |\n"
          "| --- | --- | --- | --- | --- | --- | --- |\n";
  for (const Camera& k : cameras)
    for (const Row& r : k.rows)
      text += PerFrameFormat(
          "| %s | %lld | %s | %s | %s | %s%s | %s |\n", k.serial.c_str(),
          static_cast<long long>(r.frame), Cell(r.joint_mm, r.joint_deg).c_str(),
          Cell(r.plate_mm, r.plate_deg).c_str(),
          std::isnan(r.chi2) ? "—" : PerFrameFormat("%.1f", r.chi2).c_str(),
          Cell(r.start_mm, r.start_deg).c_str(),
          std::isnan(r.start_mm) ? "" : (r.start_passed ? " ok" : " refused"),
          Cell(r.alone_mm, r.alone_deg).c_str());
  return text;
}

bool RigPerFrameTruth::AllWithin(double max_mm, double max_deg) const {
  for (std::size_t c = 1; c < cameras.size(); ++c)  // camera 0's rows are w0_from_c0
    for (const Row& r : cameras[c].rows)
      if (!(r.joint_mm <= max_mm) || !(r.joint_deg <= max_deg)) return false;
  return true;
}

}  // namespace lifmcr::registration
