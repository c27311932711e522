#include "registration/features/marker_edges.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <vector>

namespace lifmcr::registration {
namespace {

constexpr double kProfileStepPx = 0.25;

// Bilinear grey level at (x, y), pixel centres at integers; false outside.
bool Sample(ConstImageView g, double x, double y, double* value) {
  if (!(x >= 0 && y >= 0 && x <= g.width - 1 && y <= g.height - 1)) return false;
  const int x0 = std::min(static_cast<int>(x), g.width - 2);
  const int y0 = std::min(static_cast<int>(y), g.height - 2);
  const double tx = x - x0, ty = y - y0;
  const std::uint8_t* r0 = g.Row(y0) + x0;
  const std::uint8_t* r1 = g.Row(y0 + 1) + x0;
  const double top = r0[0] + (r0[1] - r0[0]) * tx;
  const double bottom = r1[0] + (r1[1] - r1[0]) * tx;
  *value = top + (bottom - top) * ty;
  return true;
}

// Offset s along the outward normal n of the edge through p (dark inside,
// light outside). With I(s) the profile, levels I(a) and I(b) at the ends
// of a window [a, b], a step at e with the same area,
//   e = b - integral_a^b (I(s) - I(a)) ds / (I(b) - I(a)),
// is the edge itself for any symmetric blur once the window is symmetric
// about it; the window is re-centred on e until it is. (The half-level
// crossing of the interpolated profile is not: an edge along the pixel grid
// samples every profile at the same phase, and the linear interpolation of
// a sharp sigmoid between samples moves the crossing by up to 0.1 px.)
// Trapezoid rule on samples kProfileStepPx apart of the bilinear image.
bool EdgeOffset(ConstImageView g, const Eigen::Vector2d& p, const Eigen::Vector2d& n, double w,
                double min_contrast, double* s_out) {
  const int count = static_cast<int>(std::floor(2 * w / kProfileStepPx)) + 1;
  if (count < 5) return false;
  const double half_width = 0.5 * (count - 1) * kProfileStepPx;
  double e = 0;
  for (int iteration = 0; iteration < 4; ++iteration) {
    const double a = e - half_width;
    double first = 0, last = 0, area = 0, previous = 0;
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector2d q = p + (a + i * kProfileStepPx) * n;
      double value = 0;
      if (!Sample(g, q.x(), q.y(), &value)) return false;
      if (i == 0) first = value;
      if (i > 0) area += 0.5 * (previous + value) * kProfileStepPx;
      previous = value;
      last = value;
    }
    if (!(last - first >= min_contrast)) return false;
    const double next = a + 2 * half_width - (area - first * 2 * half_width) / (last - first);
    const bool settled = std::abs(next - e) < 1e-3;
    e = next;
    if (!(std::abs(e) <= w)) return false;
    if (settled) break;
  }
  *s_out = e;
  return true;
}

struct Line {
  Eigen::Vector2d point, direction;
};

// Total least squares: the line through the centroid along the principal axis.
Line FitLine(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
  return {mean, eig.eigenvectors().col(1)};
}

// The fit again without the points further from the first line than three
// times the median distance (at least 0.25 px): profiles through a local
// artefact of the image (a TF pixel without depth) do not bend the line.
Line FitLineRobust(const std::vector<Eigen::Vector2d>& points, int min_points) {
  const Line first = FitLine(points);
  const Eigen::Vector2d normal(-first.direction.y(), first.direction.x());
  std::vector<double> distance;
  for (const Eigen::Vector2d& p : points) distance.push_back(std::abs(normal.dot(p - first.point)));
  std::vector<double> sorted = distance;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double limit = std::max(0.25, 3.0 * sorted[sorted.size() / 2]);
  std::vector<Eigen::Vector2d> kept;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (distance[i] <= limit) kept.push_back(points[i]);
  return static_cast<int>(kept.size()) >= min_points ? FitLine(kept) : first;
}

bool Intersect(const Line& a, const Line& b, Eigen::Vector2d* x) {
  Eigen::Matrix2d m;
  m << a.direction, -b.direction;
  if (std::abs(m.determinant()) < 1e-6) return false;
  const Eigen::Vector2d ts = m.inverse() * (b.point - a.point);
  *x = a.point + ts[0] * a.direction;
  return true;
}

// One pass: edge points from the current corners, lines, new corners.
bool RefineOnce(ConstImageView g, const MarkerEdgeOptions& o,
                std::array<Eigen::Vector2d, 4>* corners) {
  const std::array<Eigen::Vector2d, 4>& q = *corners;
  const Eigen::Vector2d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
  // Edge i runs q_i -> q_{i+1}; its points in the half nearest q_i and in
  // the half nearest q_{i+1}.
  std::array<std::vector<Eigen::Vector2d>, 4> near_start, near_end;
  std::array<double, 4> margin{};
  for (int i = 0; i < 4; ++i) {
    // The other edge at the corner is t sin(angle) away from a point t along
    // this one: keep the profile and its blur clear of it.
    const Eigen::Vector2d a = (q[(i + 3) % 4] - q[i]).normalized();
    const Eigen::Vector2d b = (q[(i + 1) % 4] - q[i]).normalized();
    const double sine = std::abs(a.x() * b.y() - a.y() * b.x());
    if (sine < 0.2) return false;
    margin[i] = (o.max_profile_half_width_px + 2.0) / sine + 1.0;
  }
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& from = q[i];
    const Eigen::Vector2d& to = q[(i + 1) % 4];
    const double length = (to - from).norm();
    const Eigen::Vector2d d = (to - from) / length;
    Eigen::Vector2d n(-d.y(), d.x());
    if (n.dot(from - centre) < 0) n = -n;  // outward: dark inside, light outside
    const double w =
        std::clamp(0.4 * length / o.cells_per_side, 1.0, o.max_profile_half_width_px);
    for (double t = margin[i]; t <= length - margin[(i + 1) % 4]; t += 1.0) {
      const Eigen::Vector2d p = from + t * d;
      double s = 0;
      if (!EdgeOffset(g, p, n, w, o.min_contrast, &s)) continue;
      (t <= 0.5 * length ? near_start : near_end)[i].push_back(p + s * n);
    }
  }
  std::array<Eigen::Vector2d, 4> refined;
  for (int i = 0; i < 4; ++i) {
    std::vector<Eigen::Vector2d> before = near_end[(i + 3) % 4];  // edge q_{i-1} -> q_i
    std::vector<Eigen::Vector2d> after = near_start[i];           // edge q_i -> q_{i+1}
    if (o.whole_edges) {
      before.insert(before.end(), near_start[(i + 3) % 4].begin(), near_start[(i + 3) % 4].end());
      after.insert(after.end(), near_end[i].begin(), near_end[i].end());
    }
    if (static_cast<int>(before.size()) < o.min_points_per_half_edge ||
        static_cast<int>(after.size()) < o.min_points_per_half_edge)
      return false;
    if (!Intersect(FitLineRobust(before, o.min_points_per_half_edge),
                   FitLineRobust(after, o.min_points_per_half_edge), &refined[i]))
      return false;
  }
  *corners = refined;
  return true;
}

}  // namespace

Status MarkerEdgeOptions::Check() const {
  if (!(max_profile_half_width_px >= 1.0 && max_profile_half_width_px <= 7.0))
    return Error{"marker edges: max_profile_half_width_px: expected in [1, 7]"};
  if (!(cells_per_side >= 3)) return Error{"marker edges: cells_per_side: expected >= 3"};
  if (!(min_contrast > 0)) return Error{"marker edges: min_contrast: expected > 0"};
  if (!(min_points_per_half_edge >= 2))
    return Error{"marker edges: min_points_per_half_edge: expected >= 2"};
  if (!(max_corner_shift_px > 0)) return Error{"marker edges: max_corner_shift_px: expected > 0"};
  if (!(iterations >= 1)) return Error{"marker edges: iterations: expected >= 1"};
  return {};
}

bool RefineMarkerCorners(ConstImageView grey, const MarkerEdgeOptions& options,
                         std::array<Eigen::Vector2d, 4>* corners) {
  if (grey.data == nullptr || grey.format != PixelFormat::kMono8 || grey.width < 2 ||
      grey.height < 2)
    return false;
  std::array<Eigen::Vector2d, 4> q = *corners;
  for (int it = 0; it < options.iterations; ++it)
    if (!RefineOnce(grey, options, &q)) return false;
  for (int i = 0; i < 4; ++i)
    if ((q[i] - (*corners)[i]).norm() > options.max_corner_shift_px) return false;
  *corners = q;
  return true;
}

}  // namespace lifmcr::registration
