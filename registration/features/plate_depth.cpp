#include "registration/features/plate_depth.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

namespace lifmcr::registration {

namespace {

float NearestDepth(const std::vector<float>& depth, int width, int height, const Eigen::Vector2d& p) {
  const int x = std::clamp(static_cast<int>(std::lround(p.x())), 0, width - 1);
  const int y = std::clamp(static_cast<int>(std::lround(p.y())), 0, height - 1);
  return depth[static_cast<std::size_t>(y) * width + x];
}

// Inside the convex quad q (either orientation).
bool InsideQuad(const std::array<Eigen::Vector2d, 4>& q, const Eigen::Vector2d& p) {
  int sign = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = q[(i + 1) % 4] - q[i], d = p - q[i];
    const double cross = e.x() * d.y() - e.y() * d.x();
    const int s = cross > 0 ? 1 : cross < 0 ? -1 : 0;
    if (s == 0) continue;
    if (sign == 0) sign = s;
    else if (s != sign) return false;
  }
  return true;
}

}  // namespace

std::vector<float> PlateCornerDepths(const std::vector<PlateCorner>& corners,
                                     const std::vector<float>& tf_virtual_depth,
                                     const std::vector<float>& tf_sigma_z, int width, int height,
                                     const PlateDepthOptions& options) {
  std::vector<float> out;
  for (const PlateCorner& c : corners)
    out.push_back(NearestDepth(tf_virtual_depth, width, height, c.tf_px));
  // The markers with all four corners, their quads shrunk about the centre.
  std::map<int, std::array<Eigen::Vector2d, 4>> quads;
  std::map<int, int> count;
  for (const PlateCorner& c : corners)
    if (c.corner >= 0 && c.corner < 4) {
      quads[c.marker_id][c.corner] = c.tf_px;
      ++count[c.marker_id];
    }
  std::vector<Eigen::Vector3d> samples;  // (x, y, v)
  for (auto& [id, q] : quads) {
    if (count[id] != 4) continue;
    const Eigen::Vector2d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
    for (Eigen::Vector2d& p : q) p = centre + options.shrink * (p - centre);
    double x0 = q[0].x(), x1 = x0, y0 = q[0].y(), y1 = y0;
    for (const Eigen::Vector2d& p : q) {
      x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
    }
    for (int y = std::max(0, static_cast<int>(std::ceil(y0)));
         y <= std::min(height - 1, static_cast<int>(std::floor(y1))); ++y)
      for (int x = std::max(0, static_cast<int>(std::ceil(x0)));
           x <= std::min(width - 1, static_cast<int>(std::floor(x1))); ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * width + x;
        if (std::isnan(tf_virtual_depth[i]) || i >= tf_sigma_z.size() || std::isnan(tf_sigma_z[i]))
          continue;
        if (InsideQuad(q, Eigen::Vector2d(x, y))) samples.emplace_back(x, y, tf_virtual_depth[i]);
      }
  }
  if (static_cast<int>(samples.size()) < options.min_pixels) return out;
  // v = a + b (x - mx) + c (y - my), refitted without the points beyond 3
  // robust sigmas (1.4826 x the median absolute residual).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector3d& s : samples) mean += s.head<2>();
  mean /= static_cast<double>(samples.size());
  std::vector<bool> use(samples.size(), true);
  Eigen::Vector3d plane = Eigen::Vector3d::Zero();
  for (int round = 0; round < 3; ++round) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    int n = 0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (!use[i]) continue;
      const Eigen::Vector3d row(1, samples[i].x() - mean.x(), samples[i].y() - mean.y());
      ata += row * row.transpose();
      atb += row * samples[i].z();
      ++n;
    }
    if (n < options.min_pixels) return out;
    plane = ata.ldlt().solve(atb);
    std::vector<double> abs_residual;
    for (const Eigen::Vector3d& s : samples)
      abs_residual.push_back(std::abs(
          s.z() - plane.dot(Eigen::Vector3d(1, s.x() - mean.x(), s.y() - mean.y()))));
    std::vector<double> sorted = abs_residual;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double limit = 3 * 1.4826 * sorted[sorted.size() / 2];
    for (std::size_t i = 0; i < samples.size(); ++i) use[i] = abs_residual[i] <= limit;
  }
  for (std::size_t n = 0; n < corners.size(); ++n) {
    const Eigen::Vector2d d = corners[n].tf_px - mean;
    const double v = plane.dot(Eigen::Vector3d(1, d.x(), d.y()));
    if (v > 1) out[n] = static_cast<float>(v);
  }
  return out;
}

}  // namespace lifmcr::registration
