#pragma once
// The totally focused (TF) image of a raw frame where and at the virtual
// depth the caller chooses, without the frame's depth map: what live
// registration needs (registration/live/map_localizer.h). The rendering rule is
// RenderTotalFocus' (processing/tf_kernel.h); the virtual depth comes from
// the caller instead of the depth map:
//   Patch          a square of TF samples around a TF position at one
//                  virtual depth (a tracked map point's, predicted from the
//                  pose): a patch of 9 x 9 costs ~3 x 81 micro-image samples,
//                  where the whole chain (virtual depth of every raw pixel,
//                  TF depth, TF image) costs seconds per frame;
//   RenderAtDepth  the whole TF grid at one virtual depth (a refocused
//                  image): texture at other depths is blurred by about
//                  r (1 - v_true / v) raw pixels (r the micro-image radius),
//                  little enough for SIFT to relocalise against the map;
//   RenderAtDepths the whole TF grid with each region at its own virtual
//                  depth (RefocusDepths: a coarse grid of depths, e.g. the
//                  map points' predicted ones, interpolated between cell
//                  centres), at the cost of RenderAtDepth: each region in
//                  focus where its depth is right.
// Values are the devignetted grey (the mean of the channels of a colour
// frame), in raw grey levels.
// The geometry (micro images, devignetting gain) is the camera's, made once
// (CameraChain::Sampler); a sampler is immutable and shared by threads.

#include "config/error.h"
#include "config/mla.h"
#include "processing/plenoptic_frame.h"
#include "processing/total_focus.h"

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <vector>

namespace lifmcr::processing {

namespace detail {
class TfKernel;
}

// Virtual depth over the TF grid for RenderAtDepths: one value per cell of a
// cells_x x cells_y grid, bilinear between the cells' centres (constant
// beyond the outer ones), so that the render has no seam at a cell's edge.
struct RefocusDepths {
  int cells_x = 1, cells_y = 1;
  double tf_width = 1, tf_height = 1;
  std::vector<float> v = {3.0f};  // row-major, > 1 each
  float At(double u, double w) const;
  // The median of the depths `v` of the points at `tf_px` per cell; cells
  // without min_points points take `fallback` (> 1). Points outside the grid
  // are ignored.
  static RefocusDepths FromPoints(int tf_width, int tf_height, int cells_x, int cells_y,
                                  const std::vector<Eigen::Vector2d>& tf_px,
                                  const std::vector<double>& v, double fallback, int min_points);
};

class TfSampler {
 public:
  // `geometry`: PrepareGeometry done (the grey image is not needed).
  TfSampler(PlenopticFrame geometry, const MlaCalibration& mla);
  ~TfSampler();
  TfSampler(const TfSampler&) = delete;
  TfSampler& operator=(const TfSampler&) = delete;

  int raw_width() const { return geometry_.width; }
  int raw_height() const { return geometry_.height; }
  int tf_width() const { return geometry_.width / 2; }
  int tf_height() const { return geometry_.height / 2; }

  // size x size samples (row-major) at TF positions centre_tf + step (i -
  // (size - 1) / 2, j - (size - 1) / 2), each the mean of box x box
  // sub-samples spaced step / box (box 1: point samples), at virtual depth
  // v (> 1). False when a sample has no micro image seeing it (outside the
  // image, the vignetted border). `raw` is the camera's frame (Mono8 or
  // BGR8, the geometry's size).
  bool Patch(const ConstImageView& raw, const Eigen::Vector2d& centre_tf, double v, int size,
             double step, int box, float* out) const;
  // The same on a warped grid: sample (i, j) at centre_tf + warp (step (i -
  // (size - 1) / 2), step (j - (size - 1) / 2)) (sub-samples likewise); the
  // warp (2 x 2, TF px per TF px) maps a patch made in another view onto
  // this one (patch_tracker.h).
  bool PatchWarped(const ConstImageView& raw, const Eigen::Vector2d& centre_tf,
                   const Eigen::Matrix2d& warp, double v, int size, double step, int box,
                   float* out) const;

  // The whole TF grid at virtual depth v, Mono8 (the devignetted grey),
  // every `step`-th TF pixel: out(i, j) is the TF grid at (step i + (step -
  // 1) / 2, step j + (step - 1) / 2), so a TF position is u = step (i +
  // 1/2) - 1/2 (the centre of the step x step block; at step 2, the pixel
  // an area-averaging halving would give, point-sampled: 1/step^2 of the
  // cost, with the aliasing of point samples). `out`'s buffer is reused
  // when it has the size.
  Status RenderAtDepth(const ConstImageView& raw, double v, int step, TfImage* out) const;
  // The same grid, each TF position (u, w) at depths.At(u, w). With
  // `where` (Mono8, the output's size): only the output pixels where it is
  // non-zero are rendered, the others set to `fill` (the cost is that of
  // the pixels rendered).
  Status RenderAtDepths(const ConstImageView& raw, const RefocusDepths& depths, int step,
                        TfImage* out, const ConstImageView* where = nullptr,
                        std::uint8_t fill = 0) const;

 private:
  PlenopticFrame geometry_;
  std::unique_ptr<detail::TfKernel> kernel_;
};

}  // namespace lifmcr::processing
