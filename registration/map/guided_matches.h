#pragma once
// Map points found again in a frame whose pose is known to within a few TF
// pixels (a tracked pose): the live localizer's re-anchoring
// (registration/live/map_localizer.h), an absolute measurement against the map
// at a fraction of a relocalisation's cost.
//
// A relocalisation knows nothing of the pose: it needs the half-resolution
// TF image (fine keypoints, enough of them to survive global matching) and
// a kd-tree search of every keypoint against every map point. With the
// pose known, each keypoint is compared only with the map points whose
// projections lie within radius_px of it (a grid of the projections), the
// ratio test among those: wrong matches are rare without the global
// search, so the TF grid can be rendered coarser (every step-th pixel,
// TfSampler::RenderAtDepth at the median predicted virtual depth of the
// points in view), and SIFT on it costs 1/step^2 of the full grid's.
// Keypoints (on the rendered grid, features.h) are mapped to the TF grid by
// ScaleKeypoints, as relocalisation's are.
//
// Tried first and dropped: SIFT on small windows around each projection
// (rendered at the point's own depth, side by side in one mosaic): the
// descriptors of keypoints near a window's edge read the neighbouring
// windows, and on the small rig only 3-29 of 110 windows matched their map
// point (windows of 16-48 TF px), against ~200 inliers of a relocalisation.

#include "config/error.h"
#include "config/frames.h"
#include "config/image.h"
#include "processing/camera_model.h"
#include "processing/tf_sampler.h"
#include "registration/features/features.h"
#include "registration/map/frame_registration.h"

#include <Eigen/Core>

#include <vector>

namespace lifmcr::registration {

struct GuidedMatchOptions {
  GuidedMatchOptions() {
    features.max_features = 1500;
    features.spread_cells = 4;
  }
  // The TF grid is rendered every step-th pixel, the largest step up to
  // max_step (1..4) that keeps the rendered image's longer side >= min_side_px
  // (>= 64), raised further (up to 8) while the longer side exceeds
  // max_side_px (>= min_side_px), so that a larger sensor is matched on an
  // image of about the size that served medium. Before (max_step 3,
  // max_side_px 700): small (TF 512 x 384) 2, medium (1640 x 1237) 3, r32
  // (3280 x 2474) 5 (656 px). r32, 40 frames
  // two triggers apart, re-anchorings (4-6 a run): step 3 took 710 ms of
  // SIFT each (more than a relocalisation's 260 ms at step 4); step 4
  // 550-625 ms, frames at 2.58 mm median; step 5 170-290 ms, 2.0 mm; step 6
  // 170-230 ms, 3.1 mm.
  // Medium, frames 10+ of the drift test (test_map_localizer): step 3 re-anchored
  // with 256 inliers at 1.74 mm, step 4 with 148 at 3.21 mm (worse than the
  // tracked pose it replaced, 2.4 mm), step 2 297 at 1.44 mm for the SIFT time
  // of a relocalisation; 800 keypoints instead of 1500 at step 3: 184 at 2.48 mm.
  // With the renders refocused per region and the patches warped (the
  // tracked stretches no longer drift) the re-anchoring's own error decides
  // the extrinsics: medium, 20 frames (test_map_localizer,
  // ExtrinsicsAlongTheSequence...): step 3 (max_step 3, max_side_px 700)
  // 0.80 mm / 0.040 deg median, p90 1.17 mm, a stretch's frames 0.4-1.25 mm
  // after their re-anchoring; step 2 0.56 mm / 0.029 deg, p90 0.76 mm,
  // 407 inliers against 332, for about twice the SIFT time of a
  // re-anchoring (a relocalisation's). Live, that time decides: at step 2 a
  // re-anchoring took 286-301 ms, the poses fell behind their frames, fewer
  // frames could be tracked (112-130 of 200, 43-48 relocalised) and the
  // extrinsics came at 4.4-4.8 per second per camera, 0.93 mm / 0.038 deg
  // median; at step 3 155-171 ms, 180-245 of 250-310 tracked, 6.1-7.6 per
  // second, 0.49-0.73 mm / 0.026-0.032 deg (bench_live --preset medium
  // --seconds 20 --runs track, quiet 2 cores, two runs each). So step 3
  // where the grid allows, at most 820 px: small 2, medium 3 (547 px), r32
  // 4 (820 px). At r32 each anchor alone, 8 triggers frame by frame
  // (docs/registration.md), is 0.13-1.80 mm at step 4 (median 0.86 mm, 131
  // inliers, 173 CPU-ms a re-anchoring), 0.10-0.46 mm at step 3 (0.36 mm,
  // 205 inliers, 281 CPU-ms; max_side_px 1100), but live (bench_live
  // --preset r32 --frames 8, quiet) step 3 fell from 4.14 to 1.70
  // extrinsics/s per camera and from 0.545 to 0.785 mm: the longer
  // re-anchoring let more triggers pass and 30 frames were relocalised
  // instead of 12. 4000 keypoints instead of 1500 at step 4 changed nothing
  // (0.84 mm, 132 inliers: the masked render has fewer).
  int max_step = 3;
  int min_side_px = 256;
  int max_side_px = 820;
  // The step for a TF grid whose longer side is tf_longer_side_px.
  int Step(int tf_longer_side_px) const;
  // Whether that grid's matched keypoints are found again at refine_step.
  bool Refines(int tf_longer_side_px) const {
    return refine_step > 0 && Step(tf_longer_side_px) >= refine_from_step;
  }
  FeatureOptions features;  // SIFT on the rendered image
  // Each region rendered at its own virtual depth (TfSampler::RenderAtDepths):
  // the median predicted depth of the points in view per cell of a grid
  // refocus_cells wide (cells about square; cells with fewer than 3 points
  // take the median of all), so that texture off the median depth is not
  // blurred or moved; 0: the whole grid at the median (>= 0).
  int refocus_cells = 8;
  double radius_px = 6;     // TF px between a keypoint and a map point's projection (> 0)
  // SIFT keeps only the keypoints within radius_px (and a rendered pixel)
  // of a projected map point, and computes descriptors only for those
  // (DetectSift's mask): the others cannot match. The keypoints kept are
  // the same as without the mask (OpenCV retains its strongest first),
  // except that the spread selection (features.max_features) no longer
  // drops any of them for keypoints that could not match. At r32 (radius 6
  // TF px, step 4) 15 % of the render is within reach of a map point and
  // SIFT costs about 60 % of the unmasked; medium (step 3) about 60 % too.
  // false: the whole render's keypoints are described (the coarse
  // correction's radius covers most of the image).
  bool mask_keypoints = true;
  // Only the render's pixels within render_margin_px rendered pixels of
  // the keypoints SIFT may keep (those of mask_keypoints) are rendered, the
  // rest set to their mean grey (SIFT finds nothing there); < 0: the whole
  // grid. Needs refocus_cells > 0. The margin holds most of the support of
  // the keypoints that match (their blur and descriptor windows reach a few
  // rendered pixels beyond: 55-60 % of the matched keypoints come from
  // SIFT's doubled first octave, sigma 0.8-1.6 rendered px). Frame by frame
  // (docs/registration.md), margin 8: r32 (step 4) renders 48 % of its
  // pixels, 123 against 186 CPU-ms a re-anchoring, c0_from_cx 0.256 mm /
  // 0.0174 deg median, p90 0.397 mm, against 0.633 / 0.0374, p90 0.838
  // (margin 4: 41 %, 0.383 mm; 12: 53 %, 0.486 mm); medium (step 3) 69 %,
  // 0.320 mm / 0.0195 deg, p90 0.448 mm, against 0.302 / 0.0191, p90 0.504
  // (margin 4: 54 %, 0.301 mm, p90 0.606 mm). Fewer keypoints match (r32 186
  // against 212, medium 479 against 482); the render's share of a
  // re-anchoring is larger at r32.
  int render_margin_px = 8;
  // Each matched keypoint found again at a finer step (refine_step 1..3; 0:
  // off), where the render's step is refine_from_step or coarser: a window
  // of TF samples every refine_step TF px around it at its map point's
  // predicted virtual depth (TfSampler::Patch), 4 sigma of the keypoint + 3
  // samples to each side (a keypoint whose window would exceed
  // refine_max_half samples is not refined: the finest octave's are); SIFT
  // on the window (only within refine_reach coarse render pixels of its
  // centre described), and the keypoint nearest the centre, within
  // refine_reach coarse pixels and of a size within refine_size_ratio times
  // the coarse keypoint's, replaces it. Where none is found the coarse
  // keypoint stays. The matching keeps the coarse render's cost; the
  // refined positions get the finer step's noise. r32 (step 4), 43 triggers
  // frame by frame (docs/registration.md): c0_from_cx 0.219 against 0.633
  // mm median for 194 against 171 CPU-ms a re-anchoring (windows up to 20
  // or 24 samples: 0.535, 0.312 mm). Medium (step 3) gains less for more:
  // 0.527 against 0.650 mm, 215 against 116 CPU-ms (211 of 504 matches
  // refined), so refine_from_step 4. Re-anchored every 4 frames as before,
  // live on the 8-frame r32 rig (bench_live, quiet, alternating) it halved
  // the extrinsics (1.30 and 1.60 against 2.75 and 3.75 per second per
  // camera) and was not more accurate there (0.566 and 0.966 against 0.738
  // and 0.693 mm): its 40-50 ms a re-anchoring more pushed frames into
  // relocalisations. With a refined camera re-anchored half as often
  // (LocalizerOptions::reanchor_every_refined 8): r32 frame by frame 0.251
  // mm / 0.0165 deg median against 0.633 mm / 0.0374 deg for the same CPU
  // a frame (76 against 79 CPU-ms; camera X's own rotation error 0.013
  // against 0.032 deg: the step-4 keypoints were most of it), but live
  // (bench_live --preset r32 --frames 8, three runs each alternately, load
  // average 0.8-3.6) 2.05, 3.95 and 2.55 extrinsics/s per camera at 0.603,
  // 0.371 and 0.888 mm / 0.0455, 0.0232 and 0.0584 deg median against 3.30,
  // 3.44 and 3.19 at 0.500, 0.628 and 0.546 mm / 0.0405, 0.0346 and 0.0392
  // deg unrefined: not better live, so off (docs/registration.md). small
  // and medium are not refined either way (steps 2, 3).
  int refine_step = 0;
  int refine_from_step = 4;        // > refine_step
  int refine_max_half = 16;        // >= 4
  double refine_reach = 1;         // coarse render px (> 0)
  double refine_size_ratio = 1.5;  // >= 1
  double ratio = 0.8;       // nearest / second nearest among the candidates, (0, 1]
  Status Check() const;
};

struct GuidedMatches {
  std::vector<int> points;             // MapIndex order
  std::vector<Eigen::Vector2d> tf_px;  // the matched keypoints (TF px)
  std::vector<double> virtual_depth;   // the map point's predicted virtual depth
  int in_view = 0;                     // map points projected into the image
  int keypoints = 0;
  int step = 0;  // TF px per rendered pixel
  int refined = 0;  // matched keypoints found again at refine_step
  double rendered_fraction = 1;  // of the render's pixels (render_margin_px)
  double render_s = 0, sift_s = 0, match_s = 0;  // match_s: with the refinement
  std::string status = "ok";  // or why nothing could be matched
};

// The map point's TF position and virtual depth in a camera at cam_from_w0;
// false behind the front focal plane.
bool ProjectMapPoint(const processing::CameraModel& camera, const Pose& cam_from_w0,
                     const Eigen::Vector3d& p_in_w0, Eigen::Vector2d* tf_px, double* v);

// The map points a camera at cam_from_w0 sees inside its width x height TF
// image, binned in square cells of radius_px: the points projected within
// radius_px of a position lie in its cell and the 8 around it. Used by the
// live re-anchoring (FindGuidedMatches) and by register's re-matching of a
// refused pose (frame_registration.h, guided_rounds).
class ProjectedMapGrid {
 public:
  ProjectedMapGrid(const MapIndex& map, const processing::CameraModel& camera,
                   const Pose& cam_from_w0, double width_px, double height_px, double radius_px);
  int in_view() const { return in_view_; }
  const Eigen::Vector2d& tf_px(int point) const { return projected_[point]; }
  double virtual_depth(int point) const { return v_[point]; }
  // The points in view, cell by cell (rows of cells, top first).
  const std::vector<std::vector<int>>& cells() const { return grid_; }
  // The map point whose descriptor is nearest `descriptor` among those
  // projected within radius_px of xy, when it passes the ratio test against
  // the second nearest there (d1 < ratio2 d2 in squared distances); -1
  // otherwise. *distance2: its squared descriptor distance.
  int Nearest(const Eigen::Vector2d& xy, const float* descriptor, float ratio2,
              float* distance2) const;

 private:
  const MapIndex& map_;
  double cell_ = 1, radius2_ = 1;
  int grid_w_ = 0, grid_h_ = 0;
  std::vector<std::vector<int>> grid_;
  std::vector<Eigen::Vector2d> projected_;
  std::vector<double> v_;
  int in_view_ = 0;
};

GuidedMatches FindGuidedMatches(const MapIndex& map, const processing::CameraModel& camera,
                                const processing::TfSampler& sampler, const ConstImageView& raw,
                                const Pose& w0_from_cam, const GuidedMatchOptions& options);

}  // namespace lifmcr::registration
