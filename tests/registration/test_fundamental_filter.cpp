// The fundamental-matrix filter (registration/features/fundamental_filter.h): two
// pinhole views of random points, a third of the reference positions
// replaced by random ones; the filter must flag those and keep the rest.
#include "registration/features/fundamental_filter.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <vector>

namespace lifmcr::registration {
namespace {

Eigen::Vector2d Pinhole(const Eigen::Vector3d& p) {
  return {600 * p.x() / p.z() + 512, 600 * p.y() / p.z() + 384};
}

TEST(FundamentalFilter, FlagsPairsOffTheEpipolarLines) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> ux(-300, 300), uz(700, 1300), upx(0, 1024);
  std::normal_distribution<double> noise(0, 0.3);
  // The query camera 80 mm to the side, turned 5 degrees towards the scene.
  Eigen::Isometry3d query_from_ref = Eigen::Isometry3d::Identity();
  query_from_ref.linear() = Eigen::AngleAxisd(0.087, Eigen::Vector3d::UnitY()).toRotationMatrix();
  query_from_ref.translation() = Eigen::Vector3d(-80, 10, 5);
  std::vector<Eigen::Vector2d> query, reference;
  std::vector<bool> outlier;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d p(ux(rng), 0.75 * ux(rng), uz(rng));
    const bool bad = i % 3 == 0;
    query.push_back(Pinhole(query_from_ref * p) + Eigen::Vector2d(noise(rng), noise(rng)));
    reference.push_back(bad ? Eigen::Vector2d(upx(rng), 0.75 * upx(rng))
                            : Pinhole(p) + Eigen::Vector2d(noise(rng), noise(rng)));
    outlier.push_back(bad);
  }
  FundamentalFilterOptions options;
  const FundamentalFilterResult r = FilterByFundamental(query, reference, options);
  ASSERT_TRUE(r.applied);
  int flagged = 0, kept = 0;
  for (std::size_t i = 0; i < outlier.size(); ++i) {
    if (outlier[i]) flagged += r.inlier[i] ? 0 : 1;
    else kept += r.inlier[i] ? 1 : 0;
  }
  std::printf("%s; outliers flagged %d of 100, inliers kept %d of 200\n", r.Report().c_str(),
              flagged, kept);
  EXPECT_GE(flagged, 90);  // a random point can fall near its epipolar line
  EXPECT_GE(kept, 195);
  EXPECT_EQ(r.outliers, static_cast<int>(outlier.size()) - (kept + 100 - flagged));

  // Too few pairs: nothing removed, and it says so.
  query.resize(20);
  reference.resize(20);
  const FundamentalFilterResult few = FilterByFundamental(query, reference, options);
  EXPECT_FALSE(few.applied);
  EXPECT_EQ(few.outliers, 0);
  EXPECT_NE(few.Report().find("not applied"), std::string::npos);
  options.min_pairs = 7;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace lifmcr::registration
