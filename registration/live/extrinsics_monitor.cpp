// Extrinsic change detection (extrinsics_monitor.h).

#include "registration/live/extrinsics_monitor.h"

#include <Eigen/Geometry>

#include <cmath>

namespace lifmcr::registration {
namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// exp of a small left perturbation: exp(xi) T.
Pose ApplyLeft(const Vector6& xi, const Pose& t) {
  Pose out = Pose::Identity();
  const Eigen::Vector3d phi = xi.tail<3>();
  const double angle = phi.norm();
  const Eigen::Matrix3d dr =
      angle > 0 ? Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
  out.linear() = dr * t.rotation();
  out.translation() = dr * t.translation() + xi.head<3>();
  return out;
}

}  // namespace

Status ExtrinsicsMonitorOptions::Check() const {
  if (settle_triggers < 2) return Error{"extrinsics monitor: settle_triggers: expected >= 2"};
  if (changed_after < 1) return Error{"extrinsics monitor: changed_after: expected >= 1"};
  if (!(gate > 0)) return Error{"extrinsics monitor: gate: expected > 0"};
  if (!(sigma_floor_mm >= 0) || !std::isfinite(sigma_floor_mm))
    return Error{"extrinsics monitor: sigma_floor_mm: expected >= 0"};
  if (!(sigma_floor_deg >= 0) || !std::isfinite(sigma_floor_deg))
    return Error{"extrinsics monitor: sigma_floor_deg: expected >= 0"};
  return Status::Ok();
}

Vector6 LeftDifference(const Pose& a, const Pose& b) {
  const Eigen::Matrix3d dr = a.rotation() * b.rotation().transpose();
  const Eigen::AngleAxisd aa(dr);
  Vector6 xi;
  xi.head<3>() = a.translation() - dr * b.translation();
  xi.tail<3>() = aa.angle() * aa.axis();
  return xi;
}

Pose ExtrinsicsMonitor::Track::Running() const {
  if (accepted == 0) return anchor;
  return ApplyLeft(sum_xi / accepted, anchor);
}

void ExtrinsicsMonitor::Track::Accept(const processing::CameraPose& pose) {
  if (!has_anchor) {
    anchor = pose.transform;
    has_anchor = true;
  }
  sum_xi += LeftDifference(pose.transform, anchor);
  sum_cov += pose.covariance;
  ++accepted;
}

Eigen::Matrix<double, 6, 6> ExtrinsicsMonitor::Track::RunningCovariance() const {
  if (accepted == 0) return Matrix6::Zero();
  return sum_cov / (static_cast<double>(accepted) * accepted);
}

double ExtrinsicsMonitor::Departure(const Track& track, const processing::CameraPose& pose) const {
  Matrix6 floor = Matrix6::Zero();
  const double floor_rad = options_.sigma_floor_deg * M_PI / 180.0;
  floor.diagonal() << Eigen::Vector3d::Constant(options_.sigma_floor_mm * options_.sigma_floor_mm),
      Eigen::Vector3d::Constant(floor_rad * floor_rad);
  const Matrix6 s = pose.covariance + track.RunningCovariance() + floor;
  const Vector6 xi = LeftDifference(pose.transform, track.Running());
  return xi.dot(s.ldlt().solve(xi));
}

void ExtrinsicsMonitor::RefitWithoutOutliers(Track* track) const {
  std::vector<processing::CameraPose> kept;
  for (const processing::CameraPose& pose : track->settling)
    if (Departure(*track, pose) <= options_.gate) kept.push_back(pose);
  if (kept.size() < 2 || kept.size() == track->settling.size()) return;
  Track refit;
  refit.changes = track->changes;
  refit.last = track->last;
  for (const processing::CameraPose& pose : kept) refit.Accept(pose);
  *track = std::move(refit);
}

processing::ExtrinsicsChange ExtrinsicsMonitor::Add(const std::string& serial,
                                                    const processing::CameraPose& c0_from_cx) {
  using State = processing::ExtrinsicsChange::State;
  Track& track = tracks_[serial];
  if (c0_from_cx.status != "ok") return track.last;
  processing::ExtrinsicsChange out;
  if (track.accepted < options_.settle_triggers) {
    track.Accept(c0_from_cx);
    track.settling.push_back(c0_from_cx);
    out.state = track.changed ? State::kChanged : State::kSettling;
    if (track.accepted == options_.settle_triggers) {
      track.changed = false;
      RefitWithoutOutliers(&track);
      track.settling.clear();
    }
    out.running = track.Running();
    out.running_covariance = track.RunningCovariance();
    out.running_triggers = track.accepted;
    track.last = out;
    return out;
  }
  const Pose running = track.Running();
  out.departure = Departure(track, c0_from_cx);
  if (out.departure <= options_.gate) {
    track.Accept(c0_from_cx);
    track.departed.clear();
    out.state = State::kSteady;
    out.running = track.Running();
  } else {
    track.departed.push_back(c0_from_cx);
    out.departures_in_row = static_cast<int>(track.departed.size());
    out.state = State::kDeparting;
    out.running = running;
    if (out.departures_in_row >= options_.changed_after) {
      // The mount moved: a new running estimate from the departed poses.
      const std::vector<processing::CameraPose> departed = std::move(track.departed);
      const int changes = track.changes + 1;
      track = Track{};
      track.changes = changes;
      track.changed = true;
      for (const processing::CameraPose& pose : departed) {
        track.Accept(pose);
        track.settling.push_back(pose);
      }
      out.state = State::kChanged;
      out.running = track.Running();
    }
  }
  out.running_covariance = track.RunningCovariance();
  out.running_triggers = track.accepted;
  track.last = out;
  return out;
}

int ExtrinsicsMonitor::changes(const std::string& serial) const {
  const auto it = tracks_.find(serial);
  return it == tracks_.end() ? 0 : it->second.changes;
}

processing::CameraPose ExtrinsicsRelater::Relate(const std::string& serial,
                                                 const processing::CameraPose& w0_from_c0,
                                                 const processing::CameraPose& w0_from_cx) {
  processing::CameraPose c0_from_cx = processing::ComposeExtrinsics(w0_from_c0, w0_from_cx);
  if (monitor_) c0_from_cx.change = monitor_->Add(serial, c0_from_cx);
  return c0_from_cx;
}

}  // namespace lifmcr::registration
