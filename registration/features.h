#pragma once
// Image features for calibration and registration: SIFT (Lowe 2004, OpenCV's
// implementation) on totally focused (TF) images, and descriptor matching
// with Lowe's ratio test and a mutual (cross) check. OpenCV stays in the .cpp
// file: keypoints are plain structs, descriptors one row-major float buffer.
//
// Matching: for each query descriptor q the two nearest train descriptors
// t1, t2 (L2); kept when d(q, t1) < ratio d(q, t2) and, with cross_check, q
// is also the nearest query descriptor of t1. The neighbours are exact
// (brute force, O(nq nt)) or, with kd_tree_checks > 0, approximate:
// randomised kd-trees (FLANN, Muja & Lowe 2009) searched up to that many
// leaves, O((nq + nt) log nt); the reverse search of the cross-check then
// runs only for the train descriptors that some query chose.

#include "config/error.h"
#include "config/image.h"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace lifmcr::registration {

inline constexpr int kDescriptorSize = 128;  // SIFT

struct FeatureOptions {
  int max_features = 0;              // keep the strongest N (0 = all)
  int octave_layers = 3;             // SIFT layers per octave
  double contrast_threshold = 0.04;  // SIFT DoG contrast threshold
  double edge_threshold = 10;        // SIFT edge (principal curvature ratio) threshold
  double sigma = 1.6;                // SIFT base blur
  int border_px = 4;                 // drop keypoints this close to the image border
  Status Check() const;
};

struct Keypoint {
  Eigen::Vector2f xy_px;  // image pixel (0-based, centres at integers)
  float size = 0;         // diameter of the SIFT region (px)
  float angle_deg = 0;    // orientation
  float response = 0;     // DoG response
  int octave = 0;
};

struct Features {
  std::vector<Keypoint> keypoints;
  std::vector<float> descriptors;  // keypoints.size() x kDescriptorSize, row-major
  int size() const { return static_cast<int>(keypoints.size()); }
  const float* Descriptor(int i) const {
    return descriptors.data() + static_cast<std::size_t>(i) * kDescriptorSize;
  }
};

// SIFT on a Mono8 or BGR8 image (colour is converted to grey). The view is
// wrapped, not copied (OpenCV reads the caller's rows).
Status DetectSift(ConstImageView image, const FeatureOptions& options, Features* out);

struct MatchOptions {
  double ratio = 0.8;        // Lowe's ratio test (0, 1]
  bool cross_check = true;   // keep mutual nearest neighbours only
  double max_distance = 0;   // absolute L2 bound on the best distance (0 = none)
  int kd_tree_checks = 0;    // 0: exact neighbours; > 0: kd-tree leaves searched (FLANN)
  int kd_trees = 4;          // randomised kd-trees of the approximate search
  Status Check() const;
};

struct Match {
  int query = 0;  // index into the query set
  int train = 0;  // index into the train set
  float distance = 0;
  float ratio = 0;  // d1 / d2 (smaller is more distinctive)
};

// Matches query descriptors (nq x 128) against train descriptors (nt x 128),
// sorted by ratio (most distinctive first, as PROSAC wants them).
std::vector<Match> MatchDescriptors(const float* query, int nq, const float* train, int nt,
                                    const MatchOptions& options);

}  // namespace lifmcr::registration
