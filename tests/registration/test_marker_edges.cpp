// Corners of a blurred, obliquely seen marker from its edges
// (registration/features/marker_edges.h) against OpenCV's cornerSubPix, on images
// rendered with known corners: the quad is drawn with 256 samples per
// pixel near its edges, Gaussian-blurred as the TF image is, with a code-like light square
// inside the black border.

#include "registration/features/marker_edges.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace lifmcr::registration {
namespace {

constexpr int kSamples = 256;

// Whether p lies inside the convex quad q (either orientation).
bool Inside(const std::array<Eigen::Vector2d, 4>& q, const Eigen::Vector2d& p) {
  int sign = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = q[(i + 1) % 4] - q[i], d = p - q[i];
    const int s = e.x() * d.y() - e.y() * d.x() > 0 ? 1 : -1;
    if (sign != 0 && s != sign) return false;
    sign = s;
  }
  return true;
}

double DistanceToEdges(const std::array<Eigen::Vector2d, 4>& q, const Eigen::Vector2d& p) {
  double d = 1e9;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = q[(i + 1) % 4] - q[i];
    const double t = std::clamp((p - q[i]).dot(e) / e.squaredNorm(), 0.0, 1.0);
    d = std::min(d, (q[i] + t * e - p).norm());
  }
  return d;
}

// A marker's dark square with corners `q` (pixel centres at integers), a
// light square inside at the inner edge of a one-cell border (8 cells per
// side), on a light background: each pixel near an edge the mean of 256 point samples,
// then blurred with sigma px.
cv::Mat RenderMarker(const std::array<Eigen::Vector2d, 4>& q, int width, int height,
                     double sigma) {
  const Eigen::Vector2d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
  std::array<Eigen::Vector2d, 4> inner;
  for (int i = 0; i < 4; ++i) inner[i] = centre + 0.75 * (q[i] - centre);
  cv::Mat image(height, width, CV_32FC1);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector2d centre_px(x, y);
      if (DistanceToEdges(q, centre_px) > 0.75 && DistanceToEdges(inner, centre_px) > 0.75) {
        image.at<float>(y, x) = Inside(q, centre_px) && !Inside(inner, centre_px) ? 15 : 220;
        continue;
      }
      double sum = 0;
      for (int i = 0; i < kSamples; ++i) {
        // n-rooks pattern: every sample in its own row and column, so that an
        // edge along the pixel grid is resolved to 1/kSamples px.
        const Eigen::Vector2d p(x - 0.5 + (i + 0.5) / kSamples,
                                y - 0.5 + ((i * 101) % kSamples + 0.5) / kSamples);
        sum += Inside(q, p) && !Inside(inner, p) ? 15 : 220;
      }
      image.at<float>(y, x) = static_cast<float>(sum / kSamples);
    }
  cv::Mat blurred, out;
  cv::GaussianBlur(image, blurred, cv::Size(0, 0), sigma);
  blurred.convertTo(out, CV_8UC1);
  return out;
}

struct Errors {
  double rms = 0, max = 0;
};

Errors Compare(const std::array<Eigen::Vector2d, 4>& found,
               const std::array<Eigen::Vector2d, 4>& truth) {
  Errors e;
  for (int i = 0; i < 4; ++i) {
    const double d = (found[i] - truth[i]).norm();
    e.rms += d * d / 4;
    e.max = std::max(e.max, d);
  }
  e.rms = std::sqrt(e.rms);
  return e;
}

TEST(MarkerEdges, ObliqueBlurredMarkerCornersWithinAFewHundredthsOfAPixel) {
  // Perspective views of a square: corner angles from about 55 to 125 degrees.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-12, 12), sub(0, 1);
  double edges_ss = 0, subpix_ss = 0, edges_max = 0;
  int n = 0;
  for (int trial = 0; trial < 20; ++trial) {
    std::array<Eigen::Vector2d, 4> truth = {
        Eigen::Vector2d(60 + jitter(rng) + 18, 50 + jitter(rng)),
        Eigen::Vector2d(150 + jitter(rng), 45 + jitter(rng) + 10),
        Eigen::Vector2d(140 + jitter(rng) - 20, 140 + jitter(rng)),
        Eigen::Vector2d(55 + jitter(rng), 130 + jitter(rng))};
    for (Eigen::Vector2d& c : truth) c += Eigen::Vector2d(sub(rng), sub(rng));
    const double sigma = 0.8 + 0.8 * sub(rng);
    const cv::Mat image = RenderMarker(truth, 210, 190, sigma);

    // OpenCV's refinement from corners 1 px off, as ArUco's contour gives them.
    std::vector<cv::Point2f> start;
    for (const Eigen::Vector2d& c : truth)
      start.emplace_back(static_cast<float>(c.x() + 0.7), static_cast<float>(c.y() - 0.7));
    std::vector<cv::Point2f> subpix = start;
    cv::cornerSubPix(image, subpix, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01));
    std::array<Eigen::Vector2d, 4> by_subpix, by_edges;
    for (int i = 0; i < 4; ++i) {
      by_subpix[i] = Eigen::Vector2d(subpix[i].x, subpix[i].y);
      by_edges[i] = Eigen::Vector2d(start[i].x, start[i].y);
    }
    const ConstImageView view(image.data, image.cols, image.rows, image.step, PixelFormat::kMono8);
    ASSERT_TRUE(RefineMarkerCorners(view, MarkerEdgeOptions{}, &by_edges)) << trial;
    const Errors e = Compare(by_edges, truth), s = Compare(by_subpix, truth);
    edges_ss += e.rms * e.rms;
    subpix_ss += s.rms * s.rms;
    edges_max = std::max(edges_max, e.max);
    ++n;
  }
  const double edges_rms = std::sqrt(edges_ss / n), subpix_rms = std::sqrt(subpix_ss / n);
  std::printf("20 oblique markers, blur sigma 0.8-1.6 px: corners from edges RMS %.4f px (max "
              "%.4f), cornerSubPix RMS %.4f px\n",
              edges_rms, edges_max, subpix_rms);
  EXPECT_LT(edges_rms, 0.02);
  EXPECT_LT(edges_max, 0.06);
  EXPECT_LT(edges_rms, 0.1 * subpix_rms);
}

TEST(MarkerEdges, RejectsAQuadThatIsNotTheMarkersBorder) {
  const std::array<Eigen::Vector2d, 4> truth = {Eigen::Vector2d(50.3, 40.2),
                                                Eigen::Vector2d(150.1, 45.7),
                                                Eigen::Vector2d(145.4, 140.9),
                                                Eigen::Vector2d(45.6, 135.2)};
  const cv::Mat image = RenderMarker(truth, 200, 180, 1.0);
  const ConstImageView view(image.data, image.cols, image.rows, image.step, PixelFormat::kMono8);
  // A quad 20 px inside (an inner contour of the code), and one on plain background.
  const Eigen::Vector2d centre = 0.25 * (truth[0] + truth[1] + truth[2] + truth[3]);
  std::array<Eigen::Vector2d, 4> inside, off;
  for (int i = 0; i < 4; ++i) {
    inside[i] = centre + 0.6 * (truth[i] - centre);
    off[i] = truth[i] + Eigen::Vector2d(400, 0);
  }
  const std::array<Eigen::Vector2d, 4> inside_before = inside;
  EXPECT_FALSE(RefineMarkerCorners(view, MarkerEdgeOptions{}, &inside));
  EXPECT_EQ(inside, inside_before);  // untouched
  EXPECT_FALSE(RefineMarkerCorners(view, MarkerEdgeOptions{}, &off));
  MarkerEdgeOptions bad;
  bad.min_contrast = 0;
  EXPECT_FALSE(bad.Check());
  EXPECT_TRUE(MarkerEdgeOptions{}.Check());
}

}  // namespace
}  // namespace lifmcr::registration
