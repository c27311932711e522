#include "registration/features.h"

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <numeric>

namespace lifmcr::registration {

Status FeatureOptions::Check() const {
  if (max_features < 0) return Error{"feature options: max_features: expected >= 0"};
  if (octave_layers < 1) return Error{"feature options: octave_layers: expected >= 1"};
  if (!(contrast_threshold > 0)) return Error{"feature options: contrast_threshold: expected > 0"};
  if (!(edge_threshold > 0)) return Error{"feature options: edge_threshold: expected > 0"};
  if (!(sigma > 0)) return Error{"feature options: sigma: expected > 0"};
  if (border_px < 0) return Error{"feature options: border_px: expected >= 0"};
  return Status::Ok();
}

Status MatchOptions::Check() const {
  if (!(ratio > 0 && ratio <= 1)) return Error{"match options: ratio: expected in (0, 1]"};
  if (!(max_distance >= 0)) return Error{"match options: max_distance: expected >= 0"};
  return Status::Ok();
}

Status DetectSift(ConstImageView image, const FeatureOptions& options, Features* out) {
  if (Status s = options.Check(); !s) return s;
  if (image.data == nullptr || image.width <= 0 || image.height <= 0)
    return Error{"SIFT: empty image"};
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
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(options.max_features, options.octave_layers,
                                            options.contrast_threshold, options.edge_threshold,
                                            options.sigma);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  try {
    sift->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);
  } catch (const cv::Exception& e) {
    return Error{std::string("SIFT: ") + e.what()};
  }
  const float border = static_cast<float>(options.border_px);
  out->keypoints.reserve(keypoints.size());
  out->descriptors.reserve(keypoints.size() * kDescriptorSize);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const cv::KeyPoint& k = keypoints[i];
    if (k.pt.x < border || k.pt.y < border || k.pt.x > image.width - 1 - border ||
        k.pt.y > image.height - 1 - border)
      continue;
    out->keypoints.push_back(
        Keypoint{Eigen::Vector2f(k.pt.x, k.pt.y), k.size, k.angle, k.response, k.octave});
    const float* row = descriptors.ptr<float>(static_cast<int>(i));
    out->descriptors.insert(out->descriptors.end(), row, row + kDescriptorSize);
  }
  return Status::Ok();
}

std::vector<Match> MatchDescriptors(const float* query, int nq, const float* train, int nt,
                                    const MatchOptions& options) {
  std::vector<Match> matches;
  if (nq <= 0 || nt < 2 || !options.Check()) return matches;
  // Headers over the caller's buffers (no copy).
  const cv::Mat q(nq, kDescriptorSize, CV_32F, const_cast<float*>(query));
  const cv::Mat t(nt, kDescriptorSize, CV_32F, const_cast<float*>(train));
  cv::BFMatcher matcher(cv::NORM_L2, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(q, t, knn, 2);
  std::vector<cv::DMatch> backward;
  if (options.cross_check) matcher.match(t, q, backward);
  for (const std::vector<cv::DMatch>& m : knn) {
    if (m.size() < 2) continue;
    const float ratio = m[1].distance > 0 ? m[0].distance / m[1].distance : 1.0f;
    if (ratio >= options.ratio) continue;
    if (options.max_distance > 0 && m[0].distance > options.max_distance) continue;
    if (options.cross_check && backward[m[0].trainIdx].trainIdx != m[0].queryIdx) continue;
    matches.push_back(Match{m[0].queryIdx, m[0].trainIdx, m[0].distance, ratio});
  }
  std::stable_sort(matches.begin(), matches.end(),
                   [](const Match& a, const Match& b) { return a.ratio < b.ratio; });
  return matches;
}

}  // namespace lifmcr::registration
