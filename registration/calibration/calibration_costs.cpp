#include "registration/calibration/calibration_costs.h"

#include <algorithm>
#include <utility>

namespace lifmcr::registration::internal {

bool MakeMicroImageCost(const Eigen::Vector3d& x_v, const MicroImages& micro,
                        const Eigen::Vector2d& c0, double lambda0, int max_lenses, double s,
                        std::vector<int>* lenses, MicroImageCost* cost) {
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

}  // namespace lifmcr::registration::internal
