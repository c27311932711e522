#include "registration/calibration/calibration_truth.h"

#include "processing/camera_model.h"
#include "registration/calibration/calibration_costs.h"
#include "registration/calibration/calibration_problem.h"

#include <ceres/ceres.h>
#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

namespace lifmcr::registration {
namespace {

std::string Format(const char* fmt, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// cam_from_world as the cost functions take it: rotation (w, x, y, z), translation.
struct CameraBlock {
  std::array<double, 4> q{1, 0, 0, 0};
  std::array<double, 3> t{0, 0, 0};
};

CameraBlock ToCameraBlock(const Pose& world_from_cam) {
  const Pose c_from_w = world_from_cam.inverse();
  const Eigen::Quaterniond q(c_from_w.linear());
  return {{q.w(), q.x(), q.y(), q.z()},
          {c_from_w.translation().x(), c_from_w.translation().y(), c_from_w.translation().z()}};
}

// A keypoint observation with the intrinsics and the pose held: the point
// (world, mm) is the only parameter.
struct HeldCameraCost {
  const internal::MicroImageCost* micro = nullptr;
  const IntrinsicsVector* k = nullptr;
  const CameraBlock* camera = nullptr;
  template <typename T>
  bool operator()(const T* p_in_w, T* residuals) const {
    T k_t[kIntrinsicsSize], q[4], t[3];
    for (int i = 0; i < kIntrinsicsSize; ++i) k_t[i] = T((*k)[i]);
    for (int i = 0; i < 4; ++i) q[i] = T(camera->q[i]);
    for (int i = 0; i < 3; ++i) t[i] = T(camera->t[i]);
    return (*micro)(k_t, q, t, p_in_w, residuals);
  }
};

// The offset d = (dx, dy, dv) of the virtual point (observed - predicted,
// calibration_truth.h) from the residuals r = predicted - observed in the
// micro images centred at `centres` of the predicted virtual point x_v.
Eigen::Vector3d VirtualOffset(const IntrinsicsVector& k, const Eigen::Vector3d& x_v,
                              const std::vector<Eigen::Vector2d>& centres,
                              const std::vector<double>& r) {
  const double lambda = k[1] / (k[1] + k[2]);
  const Eigen::Vector2d c(k[3], k[4]);
  const double v = x_v.z();
  Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
  Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
  for (std::size_t n = 0; n < centres.size(); ++n) {
    const Eigen::Vector2d l = c + (centres[n] - c) * lambda;
    const Eigen::Vector2d lever = x_v.head<2>() - l;
    Eigen::Matrix<double, 2, 3> j;
    j << 1 / v, 0, -lever.x() / (v * v), 0, 1 / v, -lever.y() / (v * v);
    jtj += j.transpose() * j;
    jtr += j.transpose() * Eigen::Vector2d(-r[2 * n], -r[2 * n + 1]);
  }
  return jtj.ldlt().solve(jtr);
}

struct Sample {
  Eigen::Vector3d offset;  // dx, dy (raw px), dv (absolute)
  Eigen::Vector3d x_v;     // predicted virtual point
  double z_mm = 0;
  double ss = 0;  // sum of squared micro-image residuals
  int m = 0;      // their count
  double unexplained_ss = 0;  // of r + J d (what the offset leaves)
};

// Sum of squares of the residuals r (predicted - observed) less the part the
// virtual point's offset d explains (VirtualOffset).
double UnexplainedSs(const IntrinsicsVector& k, const Eigen::Vector3d& x_v,
                     const std::vector<Eigen::Vector2d>& centres, const std::vector<double>& r,
                     const Eigen::Vector3d& d) {
  const double lambda = k[1] / (k[1] + k[2]);
  const Eigen::Vector2d c(k[3], k[4]);
  const double v = x_v.z();
  double ss = 0;
  for (std::size_t n = 0; n < centres.size(); ++n) {
    const Eigen::Vector2d lever = x_v.head<2>() - (c + (centres[n] - c) * lambda);
    const Eigen::Vector2d dp = d.head<2>() / v - lever * d.z() / (v * v);
    ss += (Eigen::Vector2d(r[2 * n], r[2 * n + 1]) + dp).squaredNorm();
  }
  return ss;
}

struct Accumulator {
  std::vector<Sample> samples;
  int outliers = 0;
  TruthResiduals::Stats Stats() const {
    TruthResiduals::Stats s;
    s.observations = static_cast<int>(samples.size());
    s.outliers = outliers;
    if (samples.empty()) {
      s.rmse_px = s.mean_dx_px = s.mean_dy_px = s.median_dv_rel = s.median_v = s.median_z_mm =
          std::nan("");
      return s;
    }
    double ss = 0;
    long long m = 0;
    std::vector<double> dv, v, z;
    for (const Sample& x : samples) {
      ss += x.ss;
      m += x.m;
      s.mean_dx_px += x.offset.x();
      s.mean_dy_px += x.offset.y();
      dv.push_back(x.offset.z() / x.x_v.z());
      v.push_back(x.x_v.z());
      z.push_back(x.z_mm);
    }
    s.rmse_px = std::sqrt(ss / static_cast<double>(m));
    s.mean_dx_px /= static_cast<double>(samples.size());
    s.mean_dy_px /= static_cast<double>(samples.size());
    s.median_dv_rel = Median(dv);
    s.median_v = Median(v);
    s.median_z_mm = Median(z);
    return s;
  }
};

std::string StatsColumns(const TruthResiduals::Stats& s) {
  return Format("%d | %d | %.3f | %+.3f | %+.3f | %+.3f | %.2f | %.0f", s.observations, s.outliers,
                s.rmse_px, s.mean_dx_px, s.mean_dy_px, 100 * s.median_dv_rel, s.median_v,
                s.median_z_mm);
}

const char* kStatsHeader =
    "kept | outliers | RMSE px | mean dx px | mean dy px | median dv/v % | median v | median z mm";

}  // namespace

std::string TruthResiduals::Report() const {
  std::string text = Format(
      "Residuals at the ground truth (true intrinsics and poses held, each point fitted to its "
      "observations; %d points; outliers above %.2f px RMS). dx, dy: the virtual point's offset "
      "(observed - predicted, raw px of the virtual image, 2 per TF px) that explains an "
      "observation's micro-image residuals; dv/v its depth offset.\n\n",
      points, outlier_px);
  text += std::string("| frame | keypoints: ") + kStatsHeader +
          " | corners | corner RMSE px | corner mean dx px | corner mean dy px | corner median "
          "dv/v % |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Frame& f : frames)
    text += Format("| %lld | %s | %d | %.3f | %+.3f | %+.3f | %+.3f |\n",
                   static_cast<long long>(f.frame), StatsColumns(f.keypoints).c_str(),
                   f.corners.observations, f.corners.rmse_px, f.corners.mean_dx_px,
                   f.corners.mean_dy_px, 100 * f.corners.median_dv_rel);
  text += Format("| all | %s | | | | | |\n", StatsColumns(all).c_str());
  auto bins = [&](const char* title, const std::vector<Bin>& list) {
    text += Format("\n| %s | %s |\n|---|---|---|---|---|---|---|---|---|\n", title, kStatsHeader);
    for (const Bin& b : list)
      if (b.stats.observations + b.stats.outliers > 0)
        text += Format("| %g .. %g | %s |\n", b.lo, b.hi, StatsColumns(b.stats).c_str());
  };
  bins("predicted v", by_v);
  bins("x_v - c_x px", by_x);
  bins("y_v - c_y px", by_y);
  return text;
}

std::string TruthResiduals::Csv() const {
  std::string text =
      "frame,point,x_v_px,y_v_px,v,z_mm,dx_px,dy_px,dv,rms_px,unexplained_rms_px,lenses,"
      "size_tf_px,kept\n";
  for (const Row& r : rows)
    text += Format("%lld,%d,%.3f,%.3f,%.5f,%.2f,%.4f,%.4f,%.5f,%.4f,%.4f,%d,%.2f,%d\n",
                   static_cast<long long>(r.frame), r.point, r.x_v.x(), r.x_v.y(), r.x_v.z(),
                   r.z_mm, r.offset.x(), r.offset.y(), r.offset.z(), r.rms_px,
                   r.unexplained_rms_px, r.lenses, r.size_tf_px, r.kept ? 1 : 0);
  return text;
}

Expected<TruthResiduals> EvaluateAtTruth(const CalibrationInput& input,
                                         const CalibrationOptions& options,
                                         const processing::CameraIntrinsics& truth,
                                         const std::map<std::int64_t, Pose>& world_from_cam,
                                         const ProgressFn& progress) {
  if (Status s = options.Check(); !s) return s.error();
  if (Status s = truth.Check(); !s) return s.error();
  if (input.micro_images == nullptr) return Error{"calibration at the truth: no micro images"};
  Expected<internal::InitialMap> init =
      internal::Initialise(input, input.initial.intrinsics, options, progress);
  if (!init) return init.error();
  const internal::InitialMap& map = *init;
  const int n_frames = static_cast<int>(input.frames.size());
  const IntrinsicsVector k = ToVector(truth);
  const processing::CameraModel true_model(truth);
  const double s = input.initial.intrinsics.pixel_size_mm;
  const Eigen::Vector2d c0 = input.initial.intrinsics.PrincipalPointPx();
  const double lambda0 = input.frames_lambda > 0
                             ? input.frames_lambda
                             : processing::CameraModel(input.initial.intrinsics).lambda();
  std::vector<CameraBlock> cameras(n_frames);
  std::vector<bool> has_truth(n_frames, false);
  for (int f = 0; f < n_frames; ++f) {
    const auto it = world_from_cam.find(input.frames[f].frame);
    if (it == world_from_cam.end()) continue;
    cameras[f] = ToCameraBlock(it->second);
    has_truth[f] = true;
  }

  // Per track: its observations' costs, the point fitted with the truth held.
  struct Obs {
    int frame = 0;
    internal::MicroImageCost cost;
    double size_tf_px = 0;
    bool kept = true;
    double rms = 0;
  };
  std::vector<Accumulator> frame_keypoints(n_frames), frame_corners(n_frames);
  Accumulator all;
  const std::vector<double> v_edges{1, 3, 4, 5, 6, 8, 10, 15, 100};
  const std::vector<double> xy_edges{-2000, -1200, -800, -400, 0, 400, 800, 1200, 2000};
  std::vector<Accumulator> by_v(v_edges.size() - 1), by_x(xy_edges.size() - 1),
      by_y(xy_edges.size() - 1);
  auto bin_of = [](const std::vector<double>& edges, double x) {
    for (std::size_t b = 0; b + 1 < edges.size(); ++b)
      if (x >= edges[b] && x < edges[b + 1]) return static_cast<int>(b);
    return -1;
  };
  TruthResiduals out;
  std::vector<int> lenses;
  std::vector<std::vector<Obs>> tracks;
  std::vector<Eigen::Vector3d> points;
  for (const internal::Track& track : map.tracks) {
    if (track.observations.size() < 2) continue;
    std::vector<Obs> obs;
    for (const internal::Observation& ob : track.observations) {
      if (!has_truth[ob.frame]) continue;
      Obs o;
      o.frame = ob.frame;
      o.size_tf_px = input.frames[ob.frame].features.keypoints[ob.keypoint].size;
      const Eigen::Vector3d x_v = internal::VirtualPoint(input.frames[ob.frame], ob.keypoint);
      if (!internal::MakeMicroImageCost(x_v, *input.micro_images, c0, lambda0, options.max_lenses,
                                        s, &lenses, &o.cost))
        continue;
      obs.push_back(std::move(o));
    }
    if (obs.size() < 2) continue;
    // Start: the first observation back-projected with the true model.
    const internal::Observation& first = track.observations.front();
    Eigen::Vector3d p = track.p_in_w_mm;
    if (has_truth[first.frame]) {
      const Eigen::Vector3d x_v = internal::VirtualPoint(input.frames[first.frame], first.keypoint);
      const Eigen::Vector3d p_in_c = true_model.BackProject(x_v);
      if (p_in_c.allFinite()) p = world_from_cam.at(input.frames[first.frame].frame) * p_in_c;
    }
    tracks.push_back(std::move(obs));
    points.push_back(p);
  }
  // Fit each point with the truth held; residual RMS per observation.
  auto fit = [&](std::size_t t) {
    ceres::Problem problem;
    int blocks = 0;
    for (Obs& o : tracks[t]) {
      if (!o.kept) continue;
      const int m = 2 * static_cast<int>(o.cost.centres_px.size());
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<HeldCameraCost, ceres::DYNAMIC, 3>(
              new HeldCameraCost{&o.cost, &k, &cameras[o.frame]}, m),
          new ceres::HuberLoss(options.huber_px * std::sqrt(m / 2.0)), points[t].data());
      ++blocks;
    }
    if (blocks < 2) return;
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = 50;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
  };
  auto residuals = [&](const Obs& o, const Eigen::Vector3d& p, std::vector<double>* r) {
    r->assign(2 * o.cost.centres_px.size(), std::nan(""));
    return o.cost(k.data(), cameras[o.frame].q.data(), cameras[o.frame].t.data(), p.data(),
                  r->data());
  };
  std::vector<double> rms_all;
  std::vector<double> r;
  for (std::size_t t = 0; t < tracks.size(); ++t) {
    fit(t);
    for (Obs& o : tracks[t]) {
      o.rms = std::numeric_limits<double>::infinity();
      if (!residuals(o, points[t], &r)) continue;
      double ss = 0;
      for (const double x : r) ss += x * x;
      o.rms = std::sqrt(ss / static_cast<double>(o.cost.centres_px.size()));
      rms_all.push_back(o.rms);
    }
  }
  out.outlier_px = std::max(options.outlier_px, 3 * Median(rms_all));
  for (std::size_t t = 0; t < tracks.size(); ++t) {
    int kept = 0;
    for (Obs& o : tracks[t]) {
      o.kept = o.rms <= out.outlier_px;
      kept += o.kept ? 1 : 0;
    }
    if (kept < 2) {
      for (Obs& o : tracks[t]) o.kept = false;
    } else {
      if (kept < static_cast<int>(tracks[t].size())) fit(t);
      ++out.points;
    }
    for (const Obs& o : tracks[t]) {
      if (!o.kept) {
        ++frame_keypoints[o.frame].outliers;
        ++all.outliers;
      }
      if (!residuals(o, points[t], &r)) continue;
      const Eigen::Vector3d p_in_c =
          world_from_cam.at(input.frames[o.frame].frame).inverse() * points[t];
      double x_v[3];
      if (!ProjectToVirtual(k.data(), s, p_in_c.data(), x_v)) continue;
      Sample sample;
      sample.x_v = Eigen::Vector3d(x_v[0], x_v[1], x_v[2]);
      sample.offset = VirtualOffset(k, sample.x_v, o.cost.centres_px, r);
      sample.z_mm = p_in_c.z();
      for (const double x : r) sample.ss += x * x;
      sample.m = static_cast<int>(r.size());
      sample.unexplained_ss = UnexplainedSs(k, sample.x_v, o.cost.centres_px, r, sample.offset);
      out.rows.push_back({input.frames[o.frame].frame, static_cast<int>(t), sample.x_v,
                          sample.z_mm, sample.offset, std::sqrt(sample.ss / (sample.m / 2)),
                          std::sqrt(sample.unexplained_ss / (sample.m / 2)), sample.m / 2,
                          o.size_tf_px, o.kept});
      if (!o.kept) continue;
      frame_keypoints[o.frame].samples.push_back(sample);
      all.samples.push_back(sample);
      if (const int b = bin_of(v_edges, x_v[2]); b >= 0) by_v[b].samples.push_back(sample);
      if (const int b = bin_of(xy_edges, x_v[0] - k[3]); b >= 0) by_x[b].samples.push_back(sample);
      if (const int b = bin_of(xy_edges, x_v[1] - k[4]); b >= 0) by_y[b].samples.push_back(sample);
    }
  }

  // Plate corners at the truth (inset 0), every detected corner.
  for (int f = 0; f < n_frames; ++f) {
    if (!has_truth[f]) continue;
    const CalibrationFrame& frame = input.frames[f];
    const Pose c_from_w = world_from_cam.at(frame.frame).inverse();
    for (std::size_t n = 0; n < frame.corners.size(); ++n) {
      const PlateCorner& corner = frame.corners[n];
      internal::PlateCornerCost cost;
      cost.p_in_w_mm = corner.p_in_w_mm;
      cost.centre_in_w_mm = Eigen::Vector3d::Zero();
      for (const PlateCorner& other : frame.corners)
        if (other.marker_id == corner.marker_id) cost.centre_in_w_mm += 0.25 * other.p_in_w_mm;
      cost.pixel_size_mm = s;
      const Eigen::Vector2d x = 2.0 * corner.tf_px + Eigen::Vector2d(0.5, 0.5);
      cost.observed_px = x;
      const float v = n < frame.corner_virtual_depth.size() ? frame.corner_virtual_depth[n]
                                                            : std::nanf("");
      cost.use_micro = internal::MakeMicroImageCost(Eigen::Vector3d(x.x(), x.y(), v),
                                                    *input.micro_images, c0, lambda0,
                                                    options.max_lenses, s, &lenses, &cost.micro);
      std::vector<double> rc(cost.residuals());
      const double inset = 0;
      if (!cost(k.data(), cameras[f].q.data(), cameras[f].t.data(), &inset, rc.data())) continue;
      const Eigen::Vector3d p_in_c = c_from_w * corner.p_in_w_mm;
      double x_v[3];
      if (!ProjectToVirtual(k.data(), s, p_in_c.data(), x_v)) continue;
      Sample sample;
      sample.x_v = Eigen::Vector3d(x_v[0], x_v[1], x_v[2]);
      sample.offset = cost.use_micro ? VirtualOffset(k, sample.x_v, cost.micro.centres_px, rc)
                                     : Eigen::Vector3d(-rc[0], -rc[1], std::nan(""));
      sample.z_mm = p_in_c.z();
      for (const double e : rc) sample.ss += e * e;
      sample.m = static_cast<int>(rc.size());
      if (cost.use_micro)
        sample.unexplained_ss =
            UnexplainedSs(k, sample.x_v, cost.micro.centres_px, rc, sample.offset);
      out.rows.push_back({frame.frame, -1, sample.x_v, sample.z_mm, sample.offset,
                          std::sqrt(sample.ss / (sample.m / 2)),
                          std::sqrt(sample.unexplained_ss / (sample.m / 2)), sample.m / 2, 0.0, true});
      frame_corners[f].samples.push_back(sample);
    }
  }

  for (int f = 0; f < n_frames; ++f) {
    if (!has_truth[f]) continue;
    out.frames.push_back({input.frames[f].frame, frame_keypoints[f].Stats(),
                          frame_corners[f].Stats()});
  }
  out.all = all.Stats();
  for (std::size_t b = 0; b < by_v.size(); ++b)
    out.by_v.push_back({v_edges[b], v_edges[b + 1], by_v[b].Stats()});
  for (std::size_t b = 0; b < by_x.size(); ++b)
    out.by_x.push_back({xy_edges[b], xy_edges[b + 1], by_x[b].Stats()});
  for (std::size_t b = 0; b < by_y.size(); ++b)
    out.by_y.push_back({xy_edges[b], xy_edges[b + 1], by_y[b].Stats()});
  return out;
}

}  // namespace lifmcr::registration
