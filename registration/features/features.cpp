#include "registration/features/features.h"

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <opencv2/imgproc.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <numeric>
#include <optional>

namespace lifmcr::registration {

Status FeatureOptions::Check() const {
  if (max_features < 0) return Error{"feature options: max_features: expected >= 0"};
  if (octave_layers < 1) return Error{"feature options: octave_layers: expected >= 1"};
  if (!(contrast_threshold > 0)) return Error{"feature options: contrast_threshold: expected > 0"};
  if (!(edge_threshold > 0)) return Error{"feature options: edge_threshold: expected > 0"};
  if (!(sigma > 0)) return Error{"feature options: sigma: expected > 0"};
  if (border_px < 0) return Error{"feature options: border_px: expected >= 0"};
  if (spread_cells < 0) return Error{"feature options: spread_cells: expected >= 0"};
  if (!(image_scale > 0 && image_scale <= 1))
    return Error{"feature options: image_scale: expected in (0, 1]"};
  return Status::Ok();
}

Status MatchOptions::Check() const {
  if (!(ratio > 0 && ratio <= 1)) return Error{"match options: ratio: expected in (0, 1]"};
  if (!(max_distance >= 0)) return Error{"match options: max_distance: expected >= 0"};
  if (kd_tree_checks < 0) return Error{"match options: kd_tree_checks: expected >= 0"};
  if (kd_trees < 1) return Error{"match options: kd_trees: expected >= 1"};
  return Status::Ok();
}

Status DetectSift(ConstImageView image, const FeatureOptions& options, Features* out,
                  const ConstImageView* mask) {
  if (Status s = options.Check(); !s) return s;
  if (image.data == nullptr || image.width <= 0 || image.height <= 0)
    return Error{"SIFT: empty image"};
  if (mask != nullptr && (mask->data == nullptr || mask->format != PixelFormat::kMono8 ||
                          mask->width != image.width || mask->height != image.height))
    return Error{"SIFT: mask: expected Mono8 of the image's size " + std::to_string(image.width) +
                 " x " + std::to_string(image.height)};
  out->keypoints.clear();
  out->descriptors.clear();
  // A header over the caller's rows (no copy); grey conversion only for colour.
  const int type = image.format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  const cv::Mat view(image.height, image.width, type, const_cast<std::uint8_t*>(image.data),
                     image.stride_bytes);
  cv::Mat grey;
  if (type == CV_8UC3)
    cv::cvtColor(view, grey, cv::COLOR_BGR2GRAY);
  else
    grey = view;
  // The reduced image is a new, smaller buffer (not a copy of the caller's).
  cv::Mat scaled;
  const double scale = options.image_scale;
  if (scale < 1)
    cv::resize(grey, scaled, cv::Size(), scale, scale, cv::INTER_AREA);
  else
    scaled = grey;
  const bool spread = options.spread_cells > 0 && options.max_features > 0;
  cv::Ptr<cv::SIFT> sift =
      cv::SIFT::create(spread ? 2 * options.max_features : options.max_features,
                       options.octave_layers, options.contrast_threshold, options.edge_threshold,
                       options.sigma);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  // The mask wrapped like the image; reduced with it (nearest: a keypoint
  // is kept where its pixel's block is).
  cv::Mat mask_view, mask_scaled;
  if (mask != nullptr) {
    mask_view = cv::Mat(mask->height, mask->width, CV_8UC1, const_cast<std::uint8_t*>(mask->data),
                        mask->stride_bytes);
    if (scale < 1)
      cv::resize(mask_view, mask_scaled, scaled.size(), 0, 0, cv::INTER_NEAREST);
    else
      mask_scaled = mask_view;
  }
  try {
    if (mask != nullptr)
      sift->detectAndCompute(scaled, mask_scaled, keypoints, descriptors);
    else
      sift->detectAndCompute(scaled, cv::noArray(), keypoints, descriptors);
  } catch (const cv::Exception& e) {
    return Error{std::string("SIFT: ") + e.what()};
  }
  const float border = static_cast<float>(options.border_px);
  const float to_image = static_cast<float>(1.0 / scale);
  std::vector<int> kept;  // indices into keypoints, inside the border
  kept.reserve(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    cv::KeyPoint& k = keypoints[i];
    k.pt.x -= kSiftOffsetCorrectedPx;  // onto the pixel grid (features.h)
    k.pt.y -= kSiftOffsetCorrectedPx;
    if (scale < 1) {  // ScaleKeypoints' mapping
      k.pt.x = (k.pt.x + 0.5f) * to_image - 0.5f;
      k.pt.y = (k.pt.y + 0.5f) * to_image - 0.5f;
      k.size *= to_image;
    }
    if (k.pt.x < border || k.pt.y < border || k.pt.x > image.width - 1 - border ||
        k.pt.y > image.height - 1 - border)
      continue;
    kept.push_back(static_cast<int>(i));
  }
  if (spread && static_cast<int>(kept.size()) > options.max_features) {
    std::stable_sort(kept.begin(), kept.end(), [&](int a, int b) {
      return keypoints[a].response > keypoints[b].response;
    });
    const int cells = options.spread_cells;
    const int quota = (options.max_features + cells * cells - 1) / (cells * cells);
    std::vector<int> in_cell(static_cast<std::size_t>(cells) * cells, 0);
    std::vector<char> chosen(kept.size(), 0);
    int count = 0;
    for (std::size_t n = 0; n < kept.size() && count < options.max_features; ++n) {
      const cv::Point2f& p = keypoints[kept[n]].pt;
      const int cx = std::clamp(static_cast<int>(p.x / image.width * cells), 0, cells - 1);
      const int cy = std::clamp(static_cast<int>(p.y / image.height * cells), 0, cells - 1);
      int& c = in_cell[static_cast<std::size_t>(cy) * cells + cx];
      if (c >= quota) continue;
      ++c;
      chosen[n] = 1;
      ++count;
    }
    for (std::size_t n = 0; n < kept.size() && count < options.max_features; ++n)
      if (!chosen[n]) {
        chosen[n] = 1;
        ++count;
      }
    std::vector<int> selection;
    selection.reserve(static_cast<std::size_t>(count));
    for (std::size_t n = 0; n < kept.size(); ++n)
      if (chosen[n]) selection.push_back(kept[n]);
    kept = std::move(selection);
  }
  out->keypoints.reserve(kept.size());
  out->descriptors.reserve(kept.size() * kDescriptorSize);
  for (const int i : kept) {
    const cv::KeyPoint& k = keypoints[i];
    out->keypoints.push_back(
        Keypoint{Eigen::Vector2f(k.pt.x, k.pt.y), k.size, k.angle, k.response, k.octave});
    const float* row = descriptors.ptr<float>(i);
    out->descriptors.insert(out->descriptors.end(), row, row + kDescriptorSize);
  }
  return Status::Ok();
}

void ScaleKeypoints(double factor, Features* features) {
  const float f = static_cast<float>(factor);
  for (Keypoint& k : features->keypoints) {
    k.xy_px = (k.xy_px.array() + 0.5f) * f - 0.5f;
    k.size *= f;
  }
}

MatchOptions MapMatching() {
  MatchOptions m;
  m.kd_trees = 4;
  m.kd_tree_checks = 64;
  return m;
}

namespace {

// FLANN's kd-trees draw split dimensions with std::rand and shuffle their
// points with the calling thread's cv::theRNG(): both seeded while a forest
// is built (the thread's generator restored after), so that the same
// descriptors give the same forest, hence the same matches, whatever ran on
// the thread before.
class SeededForestRandomness {
 public:
  SeededForestRandomness() : saved_(cv::theRNG()) {
    std::srand(1);
    cv::theRNG() = cv::RNG(1);
  }
  ~SeededForestRandomness() { cv::theRNG() = saved_; }
  SeededForestRandomness(const SeededForestRandomness&) = delete;
  SeededForestRandomness& operator=(const SeededForestRandomness&) = delete;

 private:
  cv::RNG saved_;
};

// The k nearest rows of `trees` for every row of q, the rows searched in
// blocks in parallel (a FLANN search keeps its state per thread; the blocks
// write disjoint rows of the outputs). Distances squared, as FLANN gives them.
void SearchInParallel(cv::flann::Index& trees, const cv::Mat& q, int k, int checks,
                      cv::Mat* indices, cv::Mat* distances) {
  indices->create(q.rows, k, CV_32S);
  distances->create(q.rows, k, CV_32F);
  // Blocks of 128 queries: a few hundred microseconds of search each, many
  // more blocks than cores for a frame's keypoints.
  constexpr int kBlock = 128;
  tbb::parallel_for(tbb::blocked_range<int>(0, q.rows, kBlock),
                    [&](const tbb::blocked_range<int>& r) {
                      cv::Mat i = indices->rowRange(r.begin(), r.end());
                      cv::Mat d = distances->rowRange(r.begin(), r.end());
                      trees.knnSearch(q.rowRange(r.begin(), r.end()), i, d, k,
                                      cv::flann::SearchParams(checks));
                    });
}

// Below this many descriptor pairs brute force is as fast as building trees
// (trees kept in a DescriptorIndex are searched whatever the count).
constexpr double kExactBelowPairs = 4e6;

bool Approximate(const MatchOptions& options, double pairs) {
  return options.kd_tree_checks > 0 && pairs >= kExactBelowPairs;
}

// Two nearest train descriptors of every query row (indices, L2 distances),
// exact, or by kd-trees: `trees` when given (built over t), else built here.
void TwoNearest(const cv::Mat& q, const cv::Mat& t, cv::flann::Index* trees,
                const MatchOptions& options, cv::Mat* indices, cv::Mat* distances) {
  if (trees == nullptr &&
      !Approximate(options, static_cast<double>(q.rows) * static_cast<double>(t.rows))) {
    cv::BFMatcher matcher(cv::NORM_L2, false);
    std::vector<std::vector<cv::DMatch>> knn;
    matcher.knnMatch(q, t, knn, 2);
    indices->create(q.rows, 2, CV_32S);
    distances->create(q.rows, 2, CV_32F);
    for (int i = 0; i < q.rows; ++i)
      for (int j = 0; j < 2; ++j) {
        const bool has = j < static_cast<int>(knn[i].size());
        indices->at<int>(i, j) = has ? knn[i][j].trainIdx : -1;
        distances->at<float>(i, j) = has ? knn[i][j].distance : 0.0f;
      }
    return;
  }
  std::optional<cv::flann::Index> local;
  if (trees == nullptr) {
    const SeededForestRandomness seeded;
    local.emplace(t, cv::flann::KDTreeIndexParams(options.kd_trees), cvflann::FLANN_DIST_L2);
    trees = &*local;
  }
  SearchInParallel(*trees, q, 2, options.kd_tree_checks, indices, distances);
  // FLANN's L2 distances are squared.
  cv::sqrt(*distances, *distances);
}

std::vector<Match> MatchRows(const cv::Mat& q, const cv::Mat& t, cv::flann::Index* trees,
                         const MatchOptions& options) {
  std::vector<Match> matches;
  const int nq = q.rows;
  cv::Mat indices, distances;
  TwoNearest(q, t, trees, options, &indices, &distances);
  std::vector<Match> candidates;
  for (int i = 0; i < nq; ++i) {
    const int best = indices.at<int>(i, 0);
    if (best < 0 || indices.at<int>(i, 1) < 0) continue;
    const float d1 = distances.at<float>(i, 0), d2 = distances.at<float>(i, 1);
    const float ratio = d2 > 0 ? d1 / d2 : 1.0f;
    if (ratio >= options.ratio) continue;
    if (options.max_distance > 0 && d1 > options.max_distance) continue;
    candidates.push_back(Match{i, best, d1, ratio});
  }
  if (options.cross_check && !candidates.empty()) {
    // Nearest query of each chosen train descriptor (the rows are copied:
    // the chosen train descriptors are a subset).
    cv::Mat chosen(static_cast<int>(candidates.size()), kDescriptorSize, CV_32F);
    for (std::size_t n = 0; n < candidates.size(); ++n)
      t.row(candidates[n].train).copyTo(chosen.row(static_cast<int>(n)));
    cv::Mat back_indices, back_distances;
    if (!Approximate(options, static_cast<double>(chosen.rows) * nq) || nq < 2) {
      cv::BFMatcher matcher(cv::NORM_L2, false);
      std::vector<cv::DMatch> backward;
      matcher.match(chosen, q, backward);
      for (std::size_t n = 0; n < candidates.size(); ++n)
        if (backward[n].trainIdx == candidates[n].query) matches.push_back(candidates[n]);
    } else {
      const SeededForestRandomness seeded;
      cv::flann::Index index(q, cv::flann::KDTreeIndexParams(options.kd_trees),
                             cvflann::FLANN_DIST_L2);
      SearchInParallel(index, chosen, 1, options.kd_tree_checks, &back_indices, &back_distances);
      for (std::size_t n = 0; n < candidates.size(); ++n)
        if (back_indices.at<int>(static_cast<int>(n), 0) == candidates[n].query)
          matches.push_back(candidates[n]);
    }
  } else {
    matches = std::move(candidates);
  }
  std::stable_sort(matches.begin(), matches.end(),
                   [](const Match& a, const Match& b) { return a.ratio < b.ratio; });
  return matches;
}

}  // namespace

std::vector<Match> MatchDescriptors(const float* query, int nq, const float* train, int nt,
                                    const MatchOptions& options) {
  if (nq <= 0 || nt < 2 || !options.Check()) return {};
  // Headers over the caller's buffers (no copy).
  const cv::Mat q(nq, kDescriptorSize, CV_32F, const_cast<float*>(query));
  const cv::Mat t(nt, kDescriptorSize, CV_32F, const_cast<float*>(train));
  return MatchRows(q, t, nullptr, options);
}

struct DescriptorIndex::Trees {
  // Built in place: cv::flann::Index owns a raw pointer and must not be copied.
  Trees(const cv::Mat& t, int kd_trees)
      : index(t, cv::flann::KDTreeIndexParams(kd_trees), cvflann::FLANN_DIST_L2) {}
  cv::flann::Index index;
};

DescriptorIndex::DescriptorIndex(std::vector<float> descriptors)
    : descriptors_(std::move(descriptors)) {}

DescriptorIndex::~DescriptorIndex() = default;

DescriptorIndex::Trees& DescriptorIndex::TreesOf(int kd_trees) const {
  std::call_once(built_, [&] {
    const cv::Mat t(size(), kDescriptorSize, CV_32F, const_cast<float*>(descriptors_.data()));
    const SeededForestRandomness seeded;
    trees_ = std::make_unique<Trees>(t, kd_trees);
  });
  return *trees_;
}

std::vector<Match> MatchDescriptors(const float* query, int nq, const DescriptorIndex& train,
                                    const MatchOptions& options) {
  const int nt = train.size();
  if (nq <= 0 || nt < 2 || !options.Check()) return {};
  const cv::Mat q(nq, kDescriptorSize, CV_32F, const_cast<float*>(query));
  const cv::Mat t(nt, kDescriptorSize, CV_32F, const_cast<float*>(train.data()));
  cv::flann::Index* trees = nullptr;
  if (options.kd_tree_checks > 0)
    trees = &train.TreesOf(options.kd_trees).index;
  return MatchRows(q, t, trees, options);
}

}  // namespace lifmcr::registration
