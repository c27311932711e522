#pragma once
// Frame-to-frame tracking of map points on the totally focused (TF) image
// by Lucas-Kanade (translation only, inverse compositional; Baker &
// Matthews 2004), with the TF image sampled where it is needed
// (processing/tf_sampler.h) at the point's virtual depth predicted from the
// pose, so no depth map and no whole TF image are made per frame.
//
// A template is the point's patch in the frame it was last seen: per level
// l (coarse to fine, sample spacing s_l = 2^l TF px; point samples: the TF
// image is smooth at the micro-image scale, and a box filter would cost
// s_l^2 samples each) (n + 2)^2 samples, n = patch_size, the margin for
// central differences. With T the template's interior, g its gradient
// (TF px units) and H = sum g g^T, a step at position p is
//   e_i = (I(p + x_i) - mean I) - (T_i - mean T),  delta = H^-1 sum g_i e_i,
//   p <- p - delta,
// zero-mean so that a change of brightness between the frames (vignetting
// of another micro image) does not move the point. Accepted when it
// converged (|delta| < 0.03 s_l px) within max_shift_px of the prediction and
// the zero-mean normalised cross-correlation of the final patch with the
// template is >= min_zncc.

#include "config/error.h"
#include "config/image.h"
#include "processing/tf_sampler.h"

#include <Eigen/Core>

#include <functional>
#include <vector>

namespace lifmcr::registration {

struct PatchTrackOptions {
  int patch_size = 9;          // samples per side (odd, 5..31)
  int levels = 2;              // 1..4: sample spacings 2^(levels-1) .. 1 TF px
  int iterations = 8;          // steps per level (>= 1)
  double min_zncc = 0.8;       // acceptance, (0, 1)
  double max_shift_px = 12;    // from the prediction (TF px, > 0)
  double min_eigen = 2.0;      // texture of a new template: smallest eigenvalue of H / n^2 (> 0)
  Status Check() const;
};

struct PatchTemplate {
  std::vector<float> samples;  // levels x (n + 2)^2, coarsest first
  // Per level: H^-1 and the interior's gradient (2 x n^2).
  std::vector<Eigen::Matrix2d> inverse_hessian;
  std::vector<std::vector<Eigen::Vector2f>> gradient;
  std::vector<float> mean;  // of the interior, per level
};

// The template of the point at centre_tf (TF px) and virtual depth v; false
// where part of it is unseen or it lacks texture (min_eigen).
bool MakePatchTemplate(const processing::TfSampler& sampler, const ConstImageView& raw,
                       const Eigen::Vector2d& centre_tf, double v, const PatchTrackOptions& options,
                       PatchTemplate* out);

// Fills size x size samples at centre + step (i - (size - 1) / 2, j - (size -
// 1) / 2) (TfSampler::Patch's layout); false where one is unseen.
using PatchSampling =
    std::function<bool(const Eigen::Vector2d& centre_tf, int size, double step, float* out)>;
// The same template from samples of any image of the TF grid (the offline TF
// image in test_map_localizer's bias measurement).
bool MakePatchTemplate(const PatchSampling& sample, const Eigen::Vector2d& centre_tf,
                       const PatchTrackOptions& options, PatchTemplate* out);

struct PatchTrack {
  bool ok = false;
  Eigen::Vector2d tf_px = Eigen::Vector2d::Zero();  // where the template is now
  double zncc = 0;
};

// The template's position in `raw` from `predicted_tf`, at virtual depth v,
// over the template's finest options.levels levels (a template may be made
// with more levels than a track uses: the coarser ones serve weak predictions).
// `warp` (2 x 2) maps the template's sample offsets into this frame (the
// view change since the template was made, predicted from the poses:
// registration/live/map_localizer.h); the frame is sampled on the warped grid,
// I(p + W x_i), the step computed in the template's coordinates and applied
// as p <- p - W delta (inverse compositional with the warp held fixed).
PatchTrack TrackPatch(const processing::TfSampler& sampler, const ConstImageView& raw,
                      const PatchTemplate& tmpl, const Eigen::Vector2d& predicted_tf, double v,
                      const PatchTrackOptions& options,
                      const Eigen::Matrix2d& warp = Eigen::Matrix2d::Identity());

}  // namespace lifmcr::registration
