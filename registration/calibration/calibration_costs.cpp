#include "registration/calibration/calibration_costs.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace lifmcr::registration::internal {

bool MakeMicroImageCost(const Eigen::Vector3d& x_v, const MicroImages& micro,
                        const Eigen::Vector2d& c0, double lambda0, int max_lenses, double s,
                        std::vector<int>* lenses, MicroImageCost* cost, bool position_only,
                        double depth_weight) {
  if (!(x_v.z() > 1)) return false;
  micro.Seeing(x_v.head<2>(), x_v.z(), c0, lambda0, lenses);
  if (lenses->size() < 2) return false;
  std::vector<std::pair<double, int>> by_distance;
  for (const int l : *lenses) {
    const Eigen::Vector2d& ck = micro.centres_px[l];
    const Eigen::Vector2d lk = c0 + (ck - c0) * lambda0;
    by_distance.emplace_back((lk + (x_v.head<2>() - lk) / x_v.z() - ck).norm(), l);
  }
  std::sort(by_distance.begin(), by_distance.end());
  if (static_cast<int>(by_distance.size()) > max_lenses) by_distance.resize(max_lenses);
  cost->pixel_size_mm = s;
  cost->depth_from_estimate = position_only;
  cost->depth_weight = std::clamp(depth_weight, 0.0, 1.0);
  cost->inverse_v_measured = 1 / x_v.z();
  cost->observed_virtual_px = x_v.head<2>();
  cost->c0_px = c0;
  cost->lambda0 = lambda0;
  cost->centres_px.clear();
  cost->observed_px.clear();
  for (const auto& [d, l] : by_distance) {
    const Eigen::Vector2d& ck = micro.centres_px[l];
    const Eigen::Vector2d lk = c0 + (ck - c0) * lambda0;
    cost->centres_px.push_back(ck);
    cost->observed_px.push_back(lk + (x_v.head<2>() - lk) / x_v.z());
  }
  return true;
}

PlateCornerCost MakePlateCornerCost(const CalibrationFrame& frame, std::size_t n,
                                    const MicroImages& micro, const Eigen::Vector2d& c0,
                                    double lambda0, int max_lenses, double pixel_size_mm,
                                    std::vector<int>* lenses) {
  const PlateCorner& corner = frame.corners[n];
  PlateCornerCost cost;
  cost.p_in_w_mm = corner.p_in_w_mm;
  cost.centre_in_w_mm = Eigen::Vector3d::Zero();
  for (const PlateCorner& other : frame.corners)
    if (other.marker_id == corner.marker_id) cost.centre_in_w_mm += 0.25 * other.p_in_w_mm;
  cost.pixel_size_mm = pixel_size_mm;
  const Eigen::Vector2d x = 2.0 * corner.tf_px + Eigen::Vector2d(0.5, 0.5);
  cost.observed_px = x;
  const float v = n < frame.corner_virtual_depth.size() ? frame.corner_virtual_depth[n]
                                                        : std::nanf("");
  cost.use_micro = MakeMicroImageCost(Eigen::Vector3d(x.x(), x.y(), v), micro, c0, lambda0,
                                      max_lenses, pixel_size_mm, lenses, &cost.micro);
  return cost;
}

}  // namespace lifmcr::registration::internal
