#include "registration/map/guided_matches.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace lifmcr::registration {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

float SquaredDistance(const float* a, const float* b) {
  float sum = 0;
  for (int k = 0; k < kDescriptorSize; ++k) {
    const float d = a[k] - b[k];
    sum += d * d;
  }
  return sum;
}

// GuidedMatchOptions::refine_step: the keypoint at *tf_px (size_px its
// diameter, TF px, found on a render of step coarse_step) found again on a
// window sampled every refine_step TF px around it; false where the window
// leaves the image or no keypoint of its size lies near the centre.
bool RefineKeypoint(const processing::TfSampler& sampler, const ConstImageView& raw, double v,
                    float size_px, int coarse_step, const GuidedMatchOptions& options,
                    Eigen::Vector2d* tf_px) {
  const double step = options.refine_step;
  // OpenCV's keypoint size is twice its scale sigma.
  const double sigma = 0.5 * size_px / step;
  const int half = std::max(4, static_cast<int>(std::ceil(4 * sigma + 3)));
  // A window too small for its scale would not find it again.
  if (half > options.refine_max_half) return false;
  const int n = 2 * half + 1;
  thread_local std::vector<float> samples;
  thread_local std::vector<std::uint8_t> window, centre;
  samples.resize(static_cast<std::size_t>(n) * n);
  if (!sampler.Patch(raw, *tf_px, v, n, step, 1, samples.data())) return false;
  window.resize(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i)
    window[i] = static_cast<std::uint8_t>(std::clamp(samples[i] + 0.5f, 0.0f, 255.0f));
  // Only keypoints within a coarse render pixel of the centre are described.
  const double reach = options.refine_reach * coarse_step / step;
  centre.assign(window.size(), 0);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      if ((i - half) * (i - half) + (j - half) * (j - half) <= reach * reach)
        centre[static_cast<std::size_t>(j) * n + i] = 255;
  const ConstImageView image(window.data(), n, n, static_cast<std::size_t>(n),
                             PixelFormat::kMono8);
  const ConstImageView mask(centre.data(), n, n, static_cast<std::size_t>(n), PixelFormat::kMono8);
  FeatureOptions fine = options.features;
  fine.max_features = 0;
  fine.spread_cells = 0;
  fine.image_scale = 1;
  Features found;
  if (!DetectSift(image, fine, &found, &mask)) return false;
  const float coarse_size = size_px / static_cast<float>(step);  // window px
  int nearest = -1;
  float nearest_d2 = std::numeric_limits<float>::infinity();
  for (int k = 0; k < found.size(); ++k) {
    const Keypoint& kp = found.keypoints[k];
    const float ratio = static_cast<float>(options.refine_size_ratio);
    if (!(kp.size <= ratio * coarse_size && kp.size >= coarse_size / ratio)) continue;
    if ((kp.xy_px - Eigen::Vector2f(half, half)).norm() > reach) continue;
    const float d2 = (kp.xy_px - Eigen::Vector2f(half, half)).squaredNorm();
    if (d2 < nearest_d2) {
      nearest_d2 = d2;
      nearest = k;
    }
  }
  if (nearest < 0) return false;
  *tf_px += step * (found.keypoints[nearest].xy_px.cast<double>() -
                    Eigen::Vector2d(half, half));
  return true;
}

}  // namespace

ProjectedMapGrid::ProjectedMapGrid(const MapIndex& map, const processing::CameraModel& camera,
                                   const Pose& cam_from_w0, double width_px, double height_px,
                                   double radius_px)
    : map_(map), cell_(radius_px), radius2_(radius_px * radius_px) {
  grid_w_ = static_cast<int>(std::ceil(width_px / cell_));
  grid_h_ = static_cast<int>(std::ceil(height_px / cell_));
  grid_.resize(static_cast<std::size_t>(grid_w_) * grid_h_);
  projected_.resize(static_cast<std::size_t>(map.size()));
  v_.assign(static_cast<std::size_t>(map.size()), 0);
  for (int j = 0; j < map.size(); ++j) {
    if (!ProjectMapPoint(camera, cam_from_w0, map.points_in_w0[j], &projected_[j], &v_[j]))
      continue;
    const Eigen::Vector2d& p = projected_[j];
    if (!(p.x() >= 0 && p.y() >= 0 && p.x() < width_px && p.y() < height_px)) continue;
    grid_[static_cast<std::size_t>(p.y() / cell_) * grid_w_ + static_cast<int>(p.x() / cell_)]
        .push_back(j);
    ++in_view_;
  }
}

int ProjectedMapGrid::Nearest(const Eigen::Vector2d& xy, const float* descriptor, float ratio2,
                              float* distance2) const {
  const int gx = static_cast<int>(std::floor(xy.x() / cell_)),
            gy = static_cast<int>(std::floor(xy.y() / cell_));
  int nearest = -1;
  float d1 = std::numeric_limits<float>::infinity(), d2 = d1;
  for (int y = std::max(0, gy - 1); y <= std::min(grid_h_ - 1, gy + 1); ++y)
    for (int x = std::max(0, gx - 1); x <= std::min(grid_w_ - 1, gx + 1); ++x)
      for (const int j : grid_[static_cast<std::size_t>(y) * grid_w_ + x]) {
        if ((projected_[j] - xy).squaredNorm() > radius2_) continue;
        const float d = SquaredDistance(
            descriptor, map_.descriptors->data() + static_cast<std::size_t>(j) * kDescriptorSize);
        if (d < d1) {
          d2 = d1;
          d1 = d;
          nearest = j;
        } else if (d < d2) {
          d2 = d;
        }
      }
  if (nearest < 0 || !(d1 < ratio2 * d2)) return -1;
  *distance2 = d1;
  return nearest;
}

int GuidedMatchOptions::Step(int tf_longer_side_px) const {
  int step = 1;
  while (step < max_step && tf_longer_side_px / (step + 1) >= min_side_px) ++step;
  while (step < 8 && tf_longer_side_px / step > max_side_px) ++step;
  return step;
}

Status GuidedMatchOptions::Check() const {
  if (max_step < 1 || max_step > 4) return Error{"guided matching: max_step: expected 1..4"};
  if (min_side_px < 64) return Error{"guided matching: min_side_px: expected >= 64"};
  if (max_side_px < min_side_px)
    return Error{"guided matching: max_side_px: expected >= min_side_px (" +
                 std::to_string(min_side_px) + ")"};
  if (Status s = features.Check(); !s) return Error{"guided matching: " + s.error().message};
  if (!(radius_px > 0)) return Error{"guided matching: radius_px: expected > 0"};
  if (refocus_cells < 0) return Error{"guided matching: refocus_cells: expected >= 0"};
  if (!(ratio > 0 && ratio <= 1)) return Error{"guided matching: ratio: expected in (0, 1]"};
  if (refine_step < 0 || refine_step > 3)
    return Error{"guided matching: refine_step: expected 0 (off) or 1..3"};
  if (refine_max_half < 4) return Error{"guided matching: refine_max_half: expected >= 4"};
  if (refine_from_step <= refine_step)
    return Error{"guided matching: refine_from_step: expected > refine_step (" +
                 std::to_string(refine_step) + ")"};
  if (!(refine_reach > 0)) return Error{"guided matching: refine_reach: expected > 0"};
  if (!(refine_size_ratio >= 1))
    return Error{"guided matching: refine_size_ratio: expected >= 1"};
  return Status::Ok();
}

bool ProjectMapPoint(const processing::CameraModel& camera, const Pose& cam_from_w0,
                     const Eigen::Vector3d& p_in_w0, Eigen::Vector2d* tf_px, double* v) {
  const Eigen::Vector3d p = cam_from_w0 * p_in_w0;
  if (!(p.z() > camera.intrinsics().main_focal_length_mm)) return false;
  const Eigen::Vector3d virtual_px = camera.Project(p);
  if (!virtual_px.allFinite() || !(virtual_px.z() > 1)) return false;
  *tf_px = processing::CameraModel::TfOfRaw(virtual_px.head<2>());
  *v = virtual_px.z();
  return true;
}

GuidedMatches FindGuidedMatches(const MapIndex& map, const processing::CameraModel& camera,
                                const processing::TfSampler& sampler, const ConstImageView& raw,
                                const Pose& w0_from_cam, const GuidedMatchOptions& options) {
  GuidedMatches out;
  const auto render_start = std::chrono::steady_clock::now();
  // The map points in view, in a grid of radius_px cells.
  const double w = sampler.tf_width(), h = sampler.tf_height();
  const ProjectedMapGrid grid(map, camera, w0_from_cam.inverse(), w, h, options.radius_px);
  out.in_view = grid.in_view();
  if (out.in_view == 0) {
    out.status = "no map point in view";
    return out;
  }
  // Rendered with each region at the predicted depth of its points
  // (refocus_cells), else at the median virtual depth of the points in view.
  std::vector<double> in_view_v;
  std::vector<Eigen::Vector2d> in_view_tf;
  for (const std::vector<int>& points : grid.cells())
    for (const int j : points) {
      in_view_v.push_back(grid.virtual_depth(j));
      in_view_tf.push_back(grid.tf_px(j));
    }
  std::vector<double> sorted_v = in_view_v;
  std::nth_element(sorted_v.begin(), sorted_v.begin() + sorted_v.size() / 2, sorted_v.end());
  const double median_v = sorted_v[sorted_v.size() / 2];
  out.step = options.Step(static_cast<int>(std::max(w, h)));
  thread_local processing::TfImage rendered;  // reused by the worker's next re-anchoring
  processing::RefocusDepths depths;
  if (options.refocus_cells > 0) {
    const int cells_y = std::max(1, static_cast<int>(std::lround(options.refocus_cells * h / w)));
    depths = processing::RefocusDepths::FromPoints(static_cast<int>(w), static_cast<int>(h),
                                                   options.refocus_cells, cells_y, in_view_tf,
                                                   in_view_v, median_v, 3);
  }
  // The rendered pixels within reach of a projected map point: render
  // pixel i is TF position step (i + 1/2) - 1/2, a disc of radius_px / step
  // rendered pixels around each projection, one more for the keypoints'
  // sub-pixel positions (grid.Nearest decides at radius_px exactly): SIFT's
  // mask (mask_keypoints). render_margin_px more around them: the pixels
  // rendered (the rest filled with the mean of those).
  const int rw = static_cast<int>(w) / out.step, rh = static_cast<int>(h) / out.step;
  thread_local std::vector<std::uint8_t> mask_pixels, render_pixels;
  const bool masked_render = options.render_margin_px >= 0 && options.refocus_cells > 0;
  if (options.mask_keypoints || masked_render) {
    mask_pixels.assign(static_cast<std::size_t>(rw) * rh, 0);
    if (masked_render) render_pixels.assign(mask_pixels.size(), 0);
    const double r = options.radius_px / out.step + 1;
    const double rr = masked_render ? r + options.render_margin_px : r;
    const int ri = static_cast<int>(std::ceil(rr));
    const double r2 = r * r, rr2 = rr * rr;
    for (const Eigen::Vector2d& tf : in_view_tf) {
      const double ci = (tf.x() + 0.5) / out.step - 0.5, cj = (tf.y() + 0.5) / out.step - 0.5;
      const int i0 = static_cast<int>(std::lround(ci)), j0 = static_cast<int>(std::lround(cj));
      for (int j = std::max(0, j0 - ri); j <= std::min(rh - 1, j0 + ri); ++j)
        for (int i = std::max(0, i0 - ri); i <= std::min(rw - 1, i0 + ri); ++i) {
          const double d2 = (i - ci) * (i - ci) + (j - cj) * (j - cj);
          const std::size_t at = static_cast<std::size_t>(j) * rw + i;
          if (d2 <= r2) mask_pixels[at] = 255;
          if (masked_render && d2 <= rr2) render_pixels[at] = 255;
        }
    }
  }
  const ConstImageView where(render_pixels.data(), rw, rh, static_cast<std::size_t>(rw),
                             PixelFormat::kMono8);
  if (Status s = options.refocus_cells > 0
                     ? sampler.RenderAtDepths(raw, depths, out.step, &rendered,
                                              masked_render ? &where : nullptr)
                     : sampler.RenderAtDepth(raw, median_v, out.step, &rendered);
      !s) {
    out.status = s.error().message;
    return out;
  }
  if (masked_render) {
    // The pixels not rendered at the rendered ones' mean grey: the least
    // contrast at the edge between them.
    std::uint64_t sum = 0, n = 0;
    for (std::size_t i = 0; i < render_pixels.size(); ++i)
      if (render_pixels[i] != 0) {
        sum += rendered.pixels[i];
        ++n;
      }
    const std::uint8_t mean = static_cast<std::uint8_t>(n > 0 ? (sum + n / 2) / n : 0);
    for (std::size_t i = 0; i < render_pixels.size(); ++i)
      if (render_pixels[i] == 0) rendered.pixels[i] = mean;
    out.rendered_fraction = static_cast<double>(n) / static_cast<double>(render_pixels.size());
  }
  out.render_s = SecondsSince(render_start);

  const auto sift_start = std::chrono::steady_clock::now();
  const ConstImageView mask(mask_pixels.data(), rw, rh, static_cast<std::size_t>(rw),
                            PixelFormat::kMono8);
  Features features;
  if (Status s = DetectSift(rendered.View(), options.features, &features,
                            options.mask_keypoints ? &mask : nullptr);
      !s) {
    out.status = s.error().message;
    return out;
  }
  if (out.step != 1) ScaleKeypoints(out.step, &features);
  out.keypoints = features.size();
  out.sift_s = SecondsSince(sift_start);

  // Each keypoint against the map points projected within radius_px; each
  // map point keeps its best keypoint (a cross check).
  const auto match_start = std::chrono::steady_clock::now();
  const float ratio2 = static_cast<float>(options.ratio * options.ratio);
  struct Best {
    int keypoint = -1;
    float distance = std::numeric_limits<float>::infinity();
  };
  std::vector<Best> best_of_point(static_cast<std::size_t>(map.size()));
  for (int i = 0; i < features.size(); ++i) {
    float d1 = 0;
    const int nearest = grid.Nearest(features.keypoints[i].xy_px.cast<double>(),
                                     features.Descriptor(i), ratio2, &d1);
    if (nearest < 0) continue;
    Best& best = best_of_point[nearest];
    if (d1 < best.distance) best = {i, d1};
  }
  std::vector<float> sizes_px;  // the matched keypoints' (TF px)
  for (int j = 0; j < map.size(); ++j) {
    const Best& best = best_of_point[j];
    if (best.keypoint < 0) continue;
    out.points.push_back(j);
    out.tf_px.push_back(features.keypoints[best.keypoint].xy_px.cast<double>());
    out.virtual_depth.push_back(grid.virtual_depth(j));
    sizes_px.push_back(features.keypoints[best.keypoint].size);
  }
  if (options.refine_step > 0 && out.step >= options.refine_from_step)
    for (std::size_t m = 0; m < out.points.size(); ++m)
      if (RefineKeypoint(sampler, raw, out.virtual_depth[m], sizes_px[m], out.step, options,
                         &out.tf_px[m]))
        ++out.refined;
  out.match_s = SecondsSince(match_start);
  return out;
}

}  // namespace lifmcr::registration
