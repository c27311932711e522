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
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace lifmcr::registration {

inline constexpr int kDescriptorSize = 128;  // SIFT

struct FeatureOptions {
  int max_features = 0;              // keep the strongest N (0 = all)
  // With max_features: the image cut into spread_cells^2 cells and each
  // cell's strongest max_features / spread_cells^2 kept first, the rest of
  // the budget from the strongest left (0: the strongest N wherever they
  // are). SIFT then detects up to 2 max_features to choose from. Keypoints
  // bunched in the most textured part of the view give a pose with a
  // narrow base (registration/estimators/pose_checks.h refuses it).
  int spread_cells = 0;              // >= 0
  // SIFT on the image resized by this factor (area averaging), keypoints
  // mapped back to the image's pixels by ScaleKeypoints. OpenCV's SIFT
  // doubles its input first, so at 1/2 it works on the image's own pixels
  // and costs about a quarter. (0, 1].
  double image_scale = 1;
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

// OpenCV's (4.x) SIFT doubles its input by linear interpolation with pixel
// centres aligned (doubled pixel c lies at c / 2 - 1/4 of the input; its
// later octaves take every second pixel, so the same holds at every octave)
// and reports c / 2: its keypoints sit this far off in +x and +y. DetectSift
// subtracts it, so a keypoint is where its feature is on the image's grid
// (the TF grid's convention, processing/camera_model.h RawOfTf, that the
// plate corners and the camera model share; bench_keypoint_position
// measures what is left).
inline constexpr float kSiftOffsetCorrectedPx = 0.25f;

// SIFT on a Mono8 or BGR8 image (colour is converted to grey). The view is
// wrapped, not copied (OpenCV reads the caller's rows). Positions on the
// image's pixel grid (OpenCV's +1/4 px removed, above), also at image_scale.
// With `mask` (Mono8, the image's size): only keypoints on its non-zero
// pixels, and descriptors only for those. OpenCV retains its strongest
// keypoints first and applies the mask before the descriptors, so the
// keypoints are those the image gives without a mask, less the masked ones,
// at a fraction of the cost where most are masked (a descriptor costs about
// as much as the detection per keypoint: guided matching, guided_matches.h).
Status DetectSift(ConstImageView image, const FeatureOptions& options, Features* out,
                  const ConstImageView* mask = nullptr);

// Keypoints found on an image reduced by 1/factor (its pixel i the block
// centred on factor (i + 1/2) - 1/2) mapped to the full image's pixels:
// x = factor (x_s + 1/2) - 1/2; sizes times factor.
void ScaleKeypoints(double factor, Features* features);

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

// Exact neighbours (brute force): the reference the approximate search is
// measured against.
inline MatchOptions ExactMatching() { return MatchOptions{}; }

// Matching one frame against a reference map (`lifmcr register`, the live
// relocalisation, the calibration's frame-to-map matching): the kd-forest
// of a DescriptorIndex, built once per map, the keypoints searched in
// parallel. Brute force grows with the map (1150 keypoints against 100 000
// points: 6.5 s of CPU a frame); the search visits kd_tree_checks leaves
// whatever the map's size (its time grows only as the map leaves the caches).
// 4 randomised kd-trees, 64 leaves searched: against brute force on real
// maps (bench_map_matching, a ground-truth map of a synthetic small rig's
// 270 triggers cut to 1700 / 20 000 / 100 000 points, ~1150 keypoints a
// frame, one thread, loaded 2-core machine) recall 0.984 / 0.958 / 0.957 of
// the exact matches at 20 / 33 / 63 ms CPU a frame; 128 leaves: 0.994 /
// 0.986 / 0.975 at 34 / 56 / 112 ms; 32 leaves: 0.963 / 0.924 / 0.910 at 14
// / 22 / 36 ms. PnP keeps as many inliers or more, at the exact matcher's
// pose error (the extra matches, precision 0.90-0.98, are mostly a map
// point's near-duplicate, which the exact second neighbour makes fail the
// ratio test). test_registration_features checks recall >= 0.97 on SIFT of
// textures (6500 descriptors).
MatchOptions MapMatching();

// Matches query descriptors (nq x 128) against train descriptors (nt x 128),
// sorted by ratio (most distinctive first, as PROSAC wants them).
std::vector<Match> MatchDescriptors(const float* query, int nq, const float* train, int nt,
                                    const MatchOptions& options);

// Train descriptors that many query sets are matched against (a reference
// map's): the descriptors (owned) and their kd-trees, built once, at the
// first approximate search, with that search's kd_trees, and shared by
// every later one (searching is thread-safe: FLANN keeps its search heaps
// per thread). With kd_tree_checks > 0 they are searched however few the
// pairs (brute force wins only against trees built per call). Rebuilding
// the trees per query set, or brute force below 4e6 pairs, cost more than
// the search itself (bench/README.md, live registration).
class DescriptorIndex {
 public:
  explicit DescriptorIndex(std::vector<float> descriptors);  // n x kDescriptorSize
  ~DescriptorIndex();
  DescriptorIndex(const DescriptorIndex&) = delete;
  DescriptorIndex& operator=(const DescriptorIndex&) = delete;
  int size() const { return static_cast<int>(descriptors_.size() / kDescriptorSize); }
  const float* data() const { return descriptors_.data(); }
  // Builds the kd-trees now (else at the first approximate search).
  void Prepare(int kd_trees) const { (void)TreesOf(kd_trees); }

 private:
  friend std::vector<Match> MatchDescriptors(const float*, int, const DescriptorIndex&,
                                             const MatchOptions&);
  struct Trees;
  Trees& TreesOf(int kd_trees) const;  // searching is non-const in FLANN, thread-safe
  std::vector<float> descriptors_;
  mutable std::once_flag built_;
  mutable std::unique_ptr<Trees> trees_;
};

// The same matches as the overload above with train = index.data().
std::vector<Match> MatchDescriptors(const float* query, int nq, const DescriptorIndex& train,
                                    const MatchOptions& options);

}  // namespace lifmcr::registration
