#include "registration/features/plate_plane.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <functional>

namespace lifmcr::registration {
namespace {

// Calls fn(u, w) for every grid pixel inside the convex quad (either
// orientation) scaled by `scale` about its centre.
void ForEachPixelIn(const PlateMarker& marker, double scale, int width, int height,
                    const std::function<void(int, int)>& fn) {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& q : marker.quad) centre += 0.25 * q;
  std::array<Eigen::Vector2d, 4> quad;
  double lo_x = 1e300, hi_x = -1e300, lo_y = 1e300, hi_y = -1e300;
  for (int k = 0; k < 4; ++k) {
    quad[k] = centre + scale * (marker.quad[k] - centre);
    lo_x = std::min(lo_x, quad[k].x());
    hi_x = std::max(hi_x, quad[k].x());
    lo_y = std::min(lo_y, quad[k].y());
    hi_y = std::max(hi_y, quad[k].y());
  }
  const int u0 = std::max(0, static_cast<int>(std::floor(lo_x)));
  const int u1 = std::min(width - 1, static_cast<int>(std::ceil(hi_x)));
  const int w0 = std::max(0, static_cast<int>(std::floor(lo_y)));
  const int w1 = std::min(height - 1, static_cast<int>(std::ceil(hi_y)));
  for (int w = w0; w <= w1; ++w)
    for (int u = u0; u <= u1; ++u) {
      // Inside: the same side of all four edges.
      int positive = 0, negative = 0;
      for (int k = 0; k < 4; ++k) {
        const Eigen::Vector2d e = quad[(k + 1) % 4] - quad[k];
        const Eigen::Vector2d p = Eigen::Vector2d(u, w) - quad[k];
        const double cross = e.x() * p.y() - e.y() * p.x();
        positive += cross >= 0;
        negative += cross <= 0;
      }
      if (positive == 4 || negative == 4) fn(u, w);
    }
}

}  // namespace

Status PlatePlaneOptions::Check() const {
  if (min_samples < 3) return Error{"plate plane: min_samples: expected >= 3"};
  if (!(reject_sigmas > 0)) return Error{"plate plane: reject_sigmas: expected > 0"};
  if (iterations < 1) return Error{"plate plane: iterations: expected >= 1"};
  if (!(region_scale >= 1 && region_scale <= 4))
    return Error{"plate plane: region_scale: expected in [1, 4]"};
  return Status::Ok();
}

Expected<PlatePlane> FitPlatePlane(const std::vector<float>& v, const std::vector<float>& sigma_z,
                                   int width, int height, const std::vector<PlateMarker>& markers,
                                   const PlatePlaneOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (width < 1 || height < 1 || v.size() != static_cast<std::size_t>(width) * height)
    return Error{"plate plane: the depth map is not width x height"};
  const bool use_sigma = sigma_z.size() == v.size();
  struct Sample {
    double u, w, v;
  };
  std::vector<Sample> samples;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // mean marker centre: conditioning
  for (const PlateMarker& m : markers) {
    for (const Eigen::Vector2d& q : m.quad) origin += q / (4.0 * markers.size());
    ForEachPixelIn(m, 1.0, width, height, [&](int u, int w) {
      const std::size_t at = static_cast<std::size_t>(w) * width + u;
      if (std::isfinite(v[at]) && v[at] > 1 && (!use_sigma || std::isfinite(sigma_z[at])))
        samples.push_back({static_cast<double>(u), static_cast<double>(w), v[at]});
    });
  }
  if (static_cast<int>(samples.size()) < options.min_samples)
    return Error{"plate plane: " + std::to_string(samples.size()) +
                 " measured virtual depths inside the markers, expected at least " +
                 std::to_string(options.min_samples)};
  std::vector<char> kept(samples.size(), 1);
  Eigen::Vector3d p(0, 0, 0);  // v = p0 + p1 (u - origin.x) + p2 (w - origin.y)
  std::vector<double> residual(samples.size()), magnitude;
  PlatePlane plane;
  for (int iteration = 0; iteration <= options.iterations; ++iteration) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    int n = 0;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      if (!kept[k]) continue;
      const Eigen::Vector3d row(1, samples[k].u - origin.x(), samples[k].w - origin.y());
      ata += row * row.transpose();
      atb += row * samples[k].v;
      ++n;
    }
    if (n < options.min_samples)
      return Error{"plate plane: " + std::to_string(n) + " samples left after rejection"};
    p = ata.ldlt().solve(atb);
    magnitude.clear();
    double ss = 0;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      const double fit = p(0) + p(1) * (samples[k].u - origin.x()) + p(2) * (samples[k].w - origin.y());
      residual[k] = (samples[k].v - fit) / fit;
      magnitude.push_back(std::abs(residual[k]));
      if (kept[k]) ss += residual[k] * residual[k];
    }
    plane.samples = n;
    plane.rms_rel = std::sqrt(ss / n);
    if (iteration == options.iterations) break;
    std::nth_element(magnitude.begin(), magnitude.begin() + magnitude.size() / 2, magnitude.end());
    const double sigma = 1.4826 * magnitude[magnitude.size() / 2];
    for (std::size_t k = 0; k < samples.size(); ++k)
      kept[k] = std::abs(residual[k]) <= options.reject_sigmas * sigma;
  }
  plane.b = p(1);
  plane.c = p(2);
  plane.a = p(0) - p(1) * origin.x() - p(2) * origin.y();
  for (const PlateMarker& m : markers) {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& q : m.quad) centre += 0.25 * q;
    if (!(plane.At(centre.x(), centre.y()) > 1))
      return Error{"plate plane: virtual depth <= 1 at a marker"};
  }
  return plane;
}

void WritePlatePlaneDepth(const PlatePlane& plane, const std::vector<PlateMarker>& markers,
                          const PlatePlaneOptions& options, int width, int height,
                          std::vector<float>* v) {
  for (const PlateMarker& m : markers)
    ForEachPixelIn(m, options.region_scale, width, height, [&](int u, int w) {
      (*v)[static_cast<std::size_t>(w) * width + u] = static_cast<float>(plane.At(u, w));
    });
}

}  // namespace lifmcr::registration
