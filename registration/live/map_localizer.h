#pragma once
// The live registration stage (processing/registration_stage.h) of the
// pipeline: a per-camera localizer against camera 0's reference map, for
// camera 0 and every camera X.
//
// Per frame of a camera (Localize), from the raw frame:
//   track        when the camera has a pose and tracked map points: the pose
//                is predicted at constant velocity in SE(3) (the last step
//                scaled to the triggers ahead: w_pred = w_last exp(k/m
//                log(w_prev^-1 w_last)), w = w0_from_cam, a step of m
//                triggers, k ahead); each tracked map point is projected
//                with it and followed by Lucas-Kanade on the TF image
//                sampled at its predicted virtual depth, on the grid its
//                template's view maps to under the prediction (warp_patches)
//                (registration/live/patch_tracker.h, processing/tf_sampler.h):
//                no depth map, no whole TF image, no SIFT; PnP on those
//                positions (few trials: the inlier ratio is high). The
//                inliers keep being tracked, each against the template it
//                began with (a fixed reference: re-made where it was found
//                each frame, every frame's tracking error was added to the
//                last), and map points the pose shows in image cells with
//                too few tracks are added (their templates at their
//                projection), up to max_tracks spread over the image. When
//                fewer than min_anchored_fraction of the inliers began in a
//                relocalised frame or were re-anchored since, the next frame
//                is re-anchored: tracked, then matched against the map
//                guided by the tracked pose (registration/map/guided_matches.h:
//                SIFT on a coarser render, each keypoint against the map
//                points projected near it), PnP on those matches; the
//                tracks kept, each template's offset from its map point
//                measured against that pose and averaged with the anchors
//                it has seen (TrackedPoint::offset, average_anchors), the
//                frame's pose the PnP on the corrected tracked positions.
//                An anchor whose shift against the tracked pose is far
//                beyond the camera's earlier anchors' is refused before it
//                is averaged (max_anchor_shift_ratio). With
//                reanchor_after_gap a frame tracked after frames were
//                skipped is re-anchored at once, and where its anchor lies
//                beyond the camera's anchors' spread the tracked pose is
//                taken to have stepped off: the anchor's pose is published
//                and the tracks go on as before the frame. Re-anchoring is also
//                periodic: after reanchor_every frames tracked
//                (reanchor_every_refined where the re-anchoring is refined;
//                sooner while the tracks average few anchors).
//                When guided matching fails the tracked pose is published
//                (re-anchoring due again at the next frame).
//   re-find      when tracking fails (or a far frame is not tried): coarse
//                guided matching from the prediction (when that fails, from
//                the last pose: refind_from_last_pose), the tracks followed
//                from its pose ("tracked"), else guided matching from it
//                ("re-anchored", the tracks begun anew); relocalised only
//                when that fails (refind_before_relocalising). A re-anchoring that a later frame of
//                its camera overtook still hands its offsets on.
//                When the prediction is weak more pyramid levels and a
//                larger shift are allowed: two more levels and four times
//                the shift with no velocity yet (the frame after a
//                relocalisation), one more and twice when widen_ahead (3)
//                or more triggers ahead (frames skipped). When tracking fails the
//                prediction is corrected by guided matching on a coarse
//                render with a wide radius and the patches tracked again
//                from the corrected pose (LocalizerOptions::correct_predictions).
//   relocalise   otherwise, or when tracking fails, or (without trying to
//                track) for a frame too far after the camera's last pose
//                where tracking has not bridged such gaps lately
//                (LocalizerOptions::min_far_track_success): SIFT on a TF image (the
//                chain's when the frame was processed, else the whole TF
//                grid refocused at half resolution (relocalise_step): each
//                region at the predicted depth of its map points when the
//                camera had a pose (TfSampler::RenderAtDepths,
//                relocalise_refocus_cells), else at the map's median depth
//                (TfSampler::RenderAtDepth), global matching against
//                every map point (ratio and cross check, kd-tree) and full
//                LO-RANSAC PnP; the tracks begin at their map points'
//                projections from the pose, the inliers first (without a
//                pose before, the render at one depth: re-anchored in the
//                same frame first, guided from the relocalised pose). A
//                frame of a camera that another worker is relocalising is
//                not localised (Counts::skipped; its pose says so in its
//                status, localisation "skipped", and is published like a
//                failed one): relocalising it too would only repeat the
//                work, and the worker is free at once for the other camera.
//                Offline (LocalizerOptions::wait_for_earlier_frames, replay
//                --rate max) it waits instead: every frame is localised.
// Every pose passes registration/estimators/pose_checks.h (tracked ones also against
// the prediction); a refused one is published with the reason as status
// and the camera relocalises at its next frame.
// The pose carries `method` "pnp", `localisation` "tracked", "re-anchored" or "relocalised" and the
// covariance in the stage's convention (a left SE(3) perturbation, (t, r)),
// converted from pose_covariance.h's (additive translation):
//   rho = dt + [t]x dr   (t the translation of w0_from_cam),
// so Sigma_stage = A Sigma A^T, A = [[I, [t]x], [0, I]].

#include "processing/registration_stage.h"
#include "registration/live/extrinsics_monitor.h"
#include "registration/map/frame_registration.h"
#include "registration/map/guided_matches.h"
#include "registration/live/patch_tracker.h"
#include "registration/estimators/pose_checks.h"
#include "registration/map/reference_map.h"

#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>

namespace lifmcr::registration {

struct LocalizerOptions {
  // Relocalisation: SIFT on the refocused TF grid at half resolution, the
  // strongest 1500 keypoints spread over 4 x 4 cells; global matching by
  // the map's kd-forest, built once (registration.match, MapMatching() of
  // features.h, FrameRegistrationOptions' default; exact matching of 4000
  // keypoints against a map of 7000 points took seconds on 2 cores;
  // bench/README.md has the stages' times before and after); the
  // fundamental filter on (the paper's; medium, 8 frames relocalised: inliers
  // 65 -> 72 % of matches, 1.59 -> 1.55 mm / 0.079 -> 0.063 deg median, the
  // matching stage's time unchanged within the load's noise;
  // test_map_localizer prints both).
  LocalizerOptions() {
    features.max_features = 1500;
    features.spread_cells = 4;
    registration.fundamental.enabled = true;
    // The Cauchy loss in the PnP's refinement: on the live path's keypoints
    // (renders refocused at one depth, SIFT on reduced images) it gave the
    // more accurate extrinsics (bench_live medium, median c0_from_cx
    // tracked: Cauchy 1.19 mm / 0.075 deg, Huber 1.32-1.46 mm / 0.081-0.085
    // deg; relocalised 1.64 against 1.72-1.83 mm), and a PnP is ~1 ms of a
    // tracked frame's 20 ms.
    registration.pnp.loss = PnpLoss::kCauchy;
  }
  FrameRegistrationOptions registration;  // relocalisation; its pnp also when tracking
  FeatureOptions features;                // relocalisation's SIFT (image_scale: see below)
  // Relocalisation renders every step-th TF pixel (TfSampler::RenderAtDepth)
  // and runs SIFT on that; the chain's TF image, when the frame was
  // processed, is used as it is. The step is relocalise_step (1..4), raised
  // (up to 4) while the rendered image's longer side stays >=
  // relocalise_min_side_px, so that a larger sensor is relocalised on an
  // image of about the same size: medium (TF 1640 px wide) at step 3 (547
  // px), r32 (3280 px) at step 4 (820 px) instead of 2 (1640 px: a
  // relocalisation took 2.9 s at r32, 29 triggers at 10 Hz, after which the
  // frames were too far from its pose to track; bench/README.md). Medium at
  // step 3 instead of 2 (min side 800): a relocalisation ~190 CPU-ms
  // instead of ~290, its own pose worse (first frame 1.5 mm against
  // 1.05-1.3) but the next re-anchoring recovers it, so the sequence's
  // median is the same frame by frame and better live
  // (docs/registration.md).
  int relocalise_step = 2;
  int relocalise_min_side_px = 540;  // >= 1
  // With a last pose, the relocalisation's render takes each region's own
  // virtual depth (TfSampler::RenderAtDepths): the median predicted depth of
  // the map points the last pose shows, per cell of a grid this many cells
  // wide (about square cells; cells with fewer than 3 points take the median
  // of all), and each keypoint that depth; 0: the whole grid at the median
  // (>= 0). Without a pose: the map's median depth, one for the whole grid.
  int relocalise_refocus_cells = 8;
  // The step for a TF grid whose longer side is tf_longer_side_px.
  int RelocaliseStep(int tf_longer_side_px) const;
  PatchTrackOptions patches;              // tracking
  PoseCheckOptions checks;                // every pose
  int max_tracks = 160;       // map points tracked per frame (>= min_tracked)
  int track_cells = 6;        // tracks spread over track_cells^2 cells of the TF image (>= 1)
  double track_margin_px = 16;  // tracks stay this far inside the TF image (>= 0)
  // Fewer tracked inliers than this: the next frame is re-anchored. A
  // tracked pose with fewer, down to the pose checks' min_inliers, is still
  // published when it passes every check (it did before only from 30: a
  // frame tracked with 20-29 inliers was relocalised, ~600 CPU-ms at medium
  // for a pose the checks accept). (>= 3)
  int min_tracked = 30;
  // A frame whose tracking failed, or a far frame relocalised without the
  // attempt (min_far_track_success), of a camera with a pose in this pass
  // is first re-found by guided matching around its prediction: `coarse`
  // from the predicted pose, the tracks followed from that pose ("tracked"
  // when that passes: Track's correction, at any distance), else `guided`
  // from that pose (or from the correction's pose when Track corrected it
  // and tracking still failed), PnP on those matches, checked; the tracks
  // begin anew at that pose's projections ("re-anchored"). Only when that
  // fails is it relocalised. At medium a re-finding costs about a
  // third of a relocalisation's CPU (coarse render and SIFT on <= 420 px,
  // then a re-anchoring's; docs/registration.md). false: relocalised.
  bool refind_before_relocalising = true;
  // When the coarse matching from the prediction fails (the re-finding's
  // or Track's correction), it is tried once more from the camera's last
  // pose before the frame is relocalised: across a gap of several triggers
  // through a turn the constant-velocity prediction points the wrong way
  // and the last pose lies nearer the frame's view (false: relocalised).
  bool refind_from_last_pose = true;
  // Re-anchoring: when fewer of a tracked pose's inliers than this fraction
  // were begun in a relocalised frame or re-anchored since
  // (TrackedPoint::anchored), the camera's next frame is re-anchored (or
  // relocalised, without guided_reanchoring), so that tracks begun from
  // tracked poses never decide the pose alone ([0, 1]; 0: never; besides
  // reanchor_every).
  double min_anchored_fraction = 0.5;
  // A camera relocalised without a pose (its render at the map's median
  // depth throughout) is re-anchored in the same frame, when
  // relocalise_refocus_cells > 0: guided matching on a render refocused per
  // region from the relocalised pose, and the tracks begin at that pose's
  // projections (medium, 20 frames: the stretch tracked from the first
  // relocalisation was at 0.8-1.5 mm, the one after a re-anchoring at
  // 0.15-0.55 mm; test_map_localizer). When that fails, at the next frame.
  // In cold_reanchor_rounds rounds, each guided from the last one's pose
  // (0: at the next frame, from its tracked pose). One round: that first
  // pose at medium 1.52 -> 0.37 mm (the tracked ones' error), at r32 2.96 ->
  // 1.58 mm, for 75-170 CPU-ms more per camera; on the CPU-time schedule the
  // rate fell (5.7 -> 5.2 extrinsics/s per camera), so 0 by default
  // (docs/registration.md, "The first pose").
  int cold_reanchor_rounds = 0;  // >= 0
  // Re-anchoring by guided matching (registration/map/guided_matches.h) from the
  // frame's tracked pose; false: by relocalisation.
  bool guided_reanchoring = true;
  GuidedMatchOptions guided;
  // A re-anchoring keeps the tracks and measures each one's template offset
  // against the re-anchored pose (TrackedPoint::offset): the offsets average
  // the anchors a template has seen (the pose it was made from and each
  // re-anchoring since, up to max_anchor_weight of them, older ones
  // weighing less beyond), the tracked positions are corrected by them and
  // the frame's pose is the PnP on the corrected positions. A tracked pose
  // then carries the mean of the anchors' errors rather than the last
  // one's (each re-anchoring's own error at medium, step 3: 0.16-0.75 mm;
  // docs/registration.md). false: every re-anchoring begins the tracks
  // anew at its pose's projections, the pose its guided PnP.
  bool average_anchors = true;
  double max_anchor_weight = 8;  // >= 1 (1: the last anchor alone)
  // A bad anchor (a guided PnP off by more than its covariance says: one r32
  // run's trigger 7 at 1.15 mm from one anchor) is refused before it is
  // averaged into the tracks' offsets: its shift against the tracked pose
  // (the median over the tracked inliers of the distance between their map
  // points' projections from the two poses, TF px) is compared with the
  // camera's earlier accepted anchors' (their RMS shift). Once
  // min_anchor_history anchors were accepted since the camera's last
  // relocalisation, a shift above max(min_anchor_shift_px,
  // max_anchor_shift_ratio x RMS) is refused: the tracked pose is
  // published (it passed every check) and re-anchoring is due again at the
  // next frame. (ratio > 1 or 0: never refused; min px >= 0; history >= 1)
  double max_anchor_shift_ratio = 3;
  double min_anchor_shift_px = 0.5;
  int min_anchor_history = 3;
  // A tracked pose that steps off after a gap: at r32 on the CPU-time
  // schedule camera X's tracked pose stepped off in one frame after frames
  // were skipped (0.54 -> 1.12 mm) and stayed off through five anchors,
  // each averaged at 1 in max_anchor_weight (docs/registration.md). A frame
  // tracked reanchor_after_gap or more triggers after its camera's last
  // pose is re-anchored at once (tracked, then guided matching from the
  // tracked pose). Its anchor is never refused: the tracked pose is the one
  // in doubt. When the anchor's shift against the tracked pose (as for
  // max_anchor_shift_ratio) exceeds max(min_anchor_shift_px,
  // step_off_shift_ratio x the RMS shift of the camera's earlier anchors),
  // once min_anchor_history anchors were accepted, the tracked pose has
  // stepped off: the frame's pose is the anchor's own (its guided PnP, not
  // averaged: averaging keeps (w - 1) / w of the tracked positions' step)
  // and the tracks go on as they were before the frame (their templates
  // and offsets untouched, none made from either pose). Otherwise the
  // anchor is averaged as any other. When the guided matching fails the
  // tracked pose is published but seeds no templates (the tracks go on as
  // before the frame) and re-anchoring is due at the next frame.
  // (0: off; else >= 2; ratio > 1)
  int reanchor_after_gap = 0;
  double step_off_shift_ratio = 2;
  // A frame after this many frames tracked since its camera's last
  // re-anchoring or relocalisation is re-anchored whatever its anchored
  // inliers (0: only by min_anchored_fraction): with average_anchors each
  // re-anchoring lowers the tracked poses' error by averaging one more
  // anchor. While the tracks average fewer than reanchor_every anchors,
  // sooner: after as many tracked frames as they average (1, 2, 3, ...), so
  // that the first stretch after a relocalisation, which rests on one or
  // two anchors, is short. Counted in frames, not triggers: live, frames
  // skipped while a camera is busy do not make the re-anchorings denser.
  // Live this was off until a frame whose tracking failed could be re-found
  // (refind_before_relocalising): the re-anchorings let a camera's frames
  // fall more than max_correction_ahead triggers behind, which were then
  // relocalised, each letting the next frames fall further behind (1.55
  // extrinsics/s per camera at medium). Re-found instead, they cost a
  // re-anchoring's time, and the periodic re-anchoring keeps the tracked
  // stretch as accurate at its end as at its start (docs/registration.md).
  int reanchor_every = 4;  // >= 0
  // The same where the re-anchoring's keypoints are refined
  // (GuidedMatchOptions::Refines: r32), each anchor being more accurate
  // (r32, each anchor alone 0.501 against 0.749 mm) and dearer (+40-50
  // CPU-ms): r32 frame by frame, refined, 8 gave 0.251 mm / 0.0165 deg at
  // 76 CPU-ms a frame, 4 0.219 mm / 0.0135 deg at 86-97 (unrefined every 4:
  // 0.633 mm / 0.0374 deg at 79). (>= 1; unused where reanchor_every is 0)
  int reanchor_every_refined = 8;
  // The interval for a camera whose TF grid's longer side is tf_longer_side_px.
  int ReanchorEvery(int tf_longer_side_px) const;
  // A prediction over skipped frames whose tracking failed (for a weak one,
  // no velocity yet or widen_ahead triggers ahead or more, the patches already got
  // more levels and a larger shift, Track) is corrected by guided matching on a coarse
  // render with a wide radius (`coarse`: SIFT on a TF render of longer side
  // <= 420 px, each keypoint against the map points projected within 120 TF
  // px of it), PnP on those matches, and the patches tracked again from
  // that pose at their usual levels and shift; relocalised when that fails
  // too. r32, frames 5 triggers apart (a relocalisation's time): the
  // constant-velocity prediction missed by 30-106 TF px (median over the
  // map points; the trajectory turns within the gap) and tracking followed
  // 2 of 111 points; 2 apart it missed by 16-28 TF px (at r32 twice
  // medium's pixels for the same angle) and followed 10-13 of ~100.
  // The correction costs ~110 ms at r32 against ~450 ms for a relocalisation.
  // Only when frames were skipped (2 or more triggers after the camera's last
  // pose): tracking that fails from the frame before is no prediction's
  // fault (small rig played forward then back: tracked through each reversal
  // from a corrected pose, frames 10+ after the relocalisation were 0.35 mm
  // worse than frames 1-3, where relocalising there kept them within 0.3 mm,
  // test_map_localizer). And only up to max_correction_ahead triggers:
  // further, the tracks' templates no longer match the view even from a
  // corrected pose and the correction's time only delays the
  // relocalisation (bench_live r32: with every frame corrected, 16 of 70
  // corrections served and a failed frame cost 990 ms instead of 559;
  // 0.89 extrinsics/s per camera instead of 1.38).
  bool correct_predictions = true;
  int max_correction_ahead = 3;  // >= 1
  // A frame this many triggers or more after its camera's last pose (with
  // a velocity) is tracked with one more pyramid level and twice the shift
  // (the templates have that level): the constant-velocity prediction's
  // miss grows with the triggers ahead. (>= 2)
  int widen_ahead = 3;
  // Frames "far" after the camera's last pose (more than max_correction_ahead
  // triggers) are tracked only where tracking has bridged such gaps: per
  // camera a running rate of the far frames whose tracking succeeded (each
  // attempt weighs 1/4 against the rate so far, which starts at 1). Below
  // min_far_track_success a far frame is relocalised without the attempt,
  // except every far_track_probe_every-th, which tries (the motion may have
  // slowed). Live at r32 a relocalisation takes 4-10 frame periods, so the
  // frame after one is far; on bench_live's orbit its tracking (with the
  // extra level and shift) failed and cost ~80 ms before the
  // relocalisation (FramesSomeTriggersApartAreEachLocalised: 5 apart, 8 of
  // 8 relocalised; run 13: a relocalised frame 561 ms in the track mode
  // against 346 ms relocalising every frame). A probe costs one such
  // attempt; one in 8 far frames, and a slowed motion is noticed within 8.
  double min_far_track_success = 0.25;  // [0, 1]; 0: always try
  int far_track_probe_every = 8;        // >= 1
  GuidedMatchOptions coarse = CoarseGuidedOptions();
  static GuidedMatchOptions CoarseGuidedOptions();
  // Each tracked patch is sampled on the grid its template's view maps to
  // under the predicted pose (TrackPatch's warp): the template's plane is
  // fronto-parallel at the point's depth in the view it was made in, and the
  // affine map of its neighbourhood (finite differences over 4 TF px) into
  // the predicted view is the warp; false: unwarped (translation only).
  bool warp_patches = true;
  bool track = true;          // false: relocalise every frame (the baseline of bench_live)
  // Offline (a replay at --rate max, where every frame is wanted and none is
  // late): a frame is localised only after its camera's earlier frames in
  // flight and any relocalisation of the camera, so it tracks from its
  // predecessor's pose (when that reached the localizer first) and is never
  // passed through (Counts::skipped stays 0). Live (false): a frame of a
  // camera being relocalised passes through, so the worker is free at once.
  bool wait_for_earlier_frames = false;
  Status Check() const;
};

class MapLocalizerStage final : public processing::RegistrationStage {
 public:
  MapLocalizerStage(const ReferenceMap& map, const LocalizerOptions& options);
  std::string name() const override { return "map-localizer"; }
  Expected<std::optional<processing::CameraPose>> Localize(
      const processing::StageFrame& frame) override;
  // The composition, then, with MonitorChanges, the change detection's verdict.
  processing::CameraPose Relate(const std::string& serial, std::int64_t trigger_index,
                                const processing::CameraPose& w0_from_c0,
                                const processing::CameraPose& w0_from_cx) override;
  // Rigidly mounted cameras: every c0_from_cx goes through change detection
  // (registration/live/extrinsics_monitor.h). Before the first frame.
  void MonitorChanges(const ExtrinsicsMonitorOptions& options);

  // Frames tracked and relocalised so far (all cameras).
  struct Counts {
    long long tracked = 0, relocalised = 0, failed = 0;
    // Frames that came while their camera was relocalising on another
    // worker: not localised (the frame passes through) rather than
    // relocalised twice at once.
    long long skipped = 0;
    // Frames re-anchoring was due for (LocalizerOptions::min_anchored_fraction):
    // re-anchored by guided matching (`guided`), else relocalised (in
    // `relocalised`) or, when that failed too, tracked.
    long long reanchored = 0;
    // Of those: relocalised (tracking failed, or guided matching failed and
    // so did the tracked pose), published tracked (guided matching failed,
    // the tracked pose passed: re-anchoring is tried again at the next
    // frame), and re-anchorings that finished after a later frame of their
    // camera (their offsets or tracks still taken over).
    long long reanchor_relocalised = 0, reanchor_kept_tracked = 0, late_reanchors = 0;
    // Re-anchorings that averaged the tracks' offsets (average_anchors)
    // rather than beginning them anew, and relocalisations without a pose
    // re-anchored in the same frame.
    long long averaged = 0, cold_reanchored = 0;
    // Anchors refused before averaging (LocalizerOptions::max_anchor_shift_ratio)
    // and the largest shift refused (TF px).
    long long refused_anchors = 0;
    double refused_anchor_shift_px = 0;
    // Frames re-anchored at once after a gap (LocalizerOptions::
    // reanchor_after_gap), of those the tracked poses caught stepping off
    // (the anchor's pose published, the tracks kept as before the frame),
    // and those whose guided matching failed (the tracked pose published,
    // seeding nothing).
    long long gap_reanchors = 0, stepped_off = 0, gap_unchecked = 0;
    double stepped_off_shift_px = 0;  // the largest caught (TF px)
    // Frames re-found by guided matching around their prediction
    // (refind_before_relocalising): attempts, successes (published
    // "re-anchored", counted in `guided`), the attempts' time.
    long long refind_attempts = 0, refound = 0;
    double refind_s = 0;
    // Of the failed attempts: the coarse matching failed (from every guide
    // tried), or the fine guided matching after it; and the attempts whose
    // coarse matching succeeded from the last pose only
    // (refind_from_last_pose), successes or not.
    long long refind_coarse_failed = 0, refind_fine_failed = 0, refind_from_last = 0;
    // Frames re-anchored by guided matching (guided_matches.h) and their
    // Localize time (tracking included); the attempts' stages and figures.
    long long guided = 0, guided_attempts = 0;
    double guided_s = 0;
    double guided_render_s = 0, guided_sift_s = 0, guided_match_s = 0, guided_pnp_s = 0;
    long long guided_windows = 0 /* map points in view */, guided_matches = 0, guided_inliers = 0;
    long long guided_refined = 0;  // matches found again at GuidedMatchOptions::refine_step
    std::string last_guided_failure;
    // Localize's time (features, matching, PnP) of the frames so counted; a
    // frame whose tracking failed pays both and counts as relocalised.
    double tracked_s = 0, relocalised_s = 0, failed_s = 0;
    // Relocalisations' time by stage (all attempts, successful or not): the
    // refocused TF render, SIFT, descriptor matching, PnP (LO-RANSAC and
    // Ceres), and seeding the tracks afterwards.
    long long relocalise_attempts = 0;
    double render_s = 0, sift_s = 0, match_s = 0, pnp_s = 0, retrack_s = 0;
    // Their matches (after the fundamental filter), PnP inliers, and the
    // matches the fundamental filter removed (FrameRegistrationOptions).
    long long relocalise_matches = 0, relocalise_inliers = 0, fundamental_outliers = 0;
    // Predictions corrected by coarse guided matching after tracking failed
    // (LocalizerOptions::correct_predictions): attempts, successes, time.
    long long corrections = 0, corrected = 0;
    double correction_s = 0;
    // Far frames (LocalizerOptions::min_far_track_success): tracking
    // attempted, succeeded, and frames relocalised without the attempt.
    long long far_attempts = 0, far_tracked = 0, far_relocalised = 0;
    std::string last_correction_failure;
    std::string last_tracking_failure;  // why the last failed tracking failed
    // "relocalisations 3, per attempt: render 310 ms, SIFT 420 ms, ...,
    // inliers 41 % of matches" (means per attempt).
    std::string StageReport() const;
  };
  Counts counts() const;

 private:
  // The camera's newest poses. Frames of one camera may be localised
  // concurrently and finish out of order: a frame that reached the host
  // before the last one that set the state (host_ns) never replaces it. A
  // frame that reached the host later but has a lower trigger index starts a
  // new pass (replay --loop numbers its triggers from 0 again): the state is
  // dropped, the frame relocalised.
  // A map point followed from frame to frame against a fixed reference:
  // its patch in the frame where its track began (never re-made where it was
  // found, so that a frame's tracking error is not added to the next's).
  struct TrackedPoint {
    int point = 0;                 // index into map_
    Eigen::Vector2d tf_px;         // where it was in the camera's last frame
    std::shared_ptr<const PatchTemplate> patch;  // its appearance where its track began
    // Begun in a relocalised or re-anchored frame (at its projection from
    // that pose) or its offset measured by a re-anchoring since, not begun
    // in a tracked frame and left so (at its projection from a tracked pose,
    // whose error it then carries on).
    bool anchored = false;
    // The template's offset from where its map point lies (template
    // coordinates, TF px): a template made at a map point's projection from
    // a pose sits off the point by that pose's error (and the map point's
    // own), and every pose tracked from it carries that error. Each
    // re-anchoring measures it again, d = W^-1 (tracked - projected from the
    // re-anchored pose) (W the warp into the frame), and the offset is the
    // weighted mean of these and of the pose it was made from (weight
    // offset_weight, the anchors it averages): the tracked position less
    // W offset is then off by the mean of the anchors' errors, not the last
    // one's (LocalizerOptions::average_anchors).
    Eigen::Vector2d offset = Eigen::Vector2d::Zero();
    double offset_weight = 1;
    // The warp into the frame it was last tracked in (tf_px is the tracked
    // position less warp * offset).
    Eigen::Matrix2d warp = Eigen::Matrix2d::Identity();
    // The view its template was made in: camera pose, TF position and
    // virtual depth (template_v 0: unknown, the patch tracked unwarped).
    Pose template_cam_from_w0 = Pose::Identity();
    Eigen::Vector2d template_tf = Eigen::Vector2d::Zero();
    double template_v = 0;
  };
  using Tracks = std::vector<TrackedPoint>;
  struct CameraState {
    bool has_pose = false;
    Pose last = Pose::Identity(), previous = Pose::Identity();
    std::int64_t last_trigger = -1, previous_trigger = -1;
    std::int64_t last_host_ns = 0;
    bool has_previous = false;
    std::shared_ptr<const Tracks> tracks;  // of the last frame (shared by concurrent frames)
    bool relocalising = false;  // a worker relocalises this camera now
    bool reanchor = false;      // the last tracked pose had too few anchored inliers
    // The tracks began at a relocalisation without a pose (its render at one
    // depth): their next re-anchoring begins them anew instead of averaging.
    bool cold = false;
    // Anchors accepted since the last relocalisation and the sum of their
    // squared shifts against the tracked pose (max_anchor_shift_ratio).
    int anchor_history = 0;
    double anchor_shift2_sum = 0;
    bool last_anchor_refused = false;  // never two refusals in a row
    std::int64_t last_anchor_trigger = -1;  // its last relocalised or re-anchored frame
    int tracked_since_anchor = 0;  // frames tracked since then (reanchor_every)
    double anchor_weight = 1;  // the anchors the last pose averages (TrackedPoint::offset_weight)
    // Prediction for `trigger` (header comment); the last pose without a previous one.
    Pose Predict(std::int64_t trigger) const;
  };
  struct Outcome;  // of one attempt (map_localizer.cpp)
  Outcome Track(const processing::CameraModel& camera, const processing::TfSampler& sampler,
                const ConstImageView& raw, const CameraState& state, std::int64_t trigger) const;
  // The tracks followed from `predicted` with `patches`, then Solve.
  Outcome TrackFrom(const processing::CameraModel& camera, const processing::TfSampler& sampler,
                    const ConstImageView& raw, const Tracks& tracks, const Pose& predicted,
                    const PatchTrackOptions& patches) const;
  // A frame whose tracking failed re-found around its prediction
  // (refind_before_relocalising): coarse guided matching from `guide`
  // (skipped when `guide_is_corrected`: Track's correction already was
  // that), then the re-anchoring's guided matching from its pose.
  // When coarse matching ran, `tracks` are first followed from its pose
  // (published "tracked" when that passes). When the coarse matching from
  // `guide` fails (or `guide` is null: Track's correction from it failed),
  // it is tried from `fallback` when given (refind_from_last_pose).
  Outcome Refind(const processing::CameraModel& camera, const processing::TfSampler& sampler,
                 const ConstImageView& raw, const Pose* guide, bool guide_is_corrected,
                 const Tracks* tracks, const Pose* fallback) const;
  // The median over `kept` of the distance (TF px) between their map points'
  // projections from a_w0_from_cam and b_w0_from_cam (max_anchor_shift_ratio).
  double MedianShiftPx(const processing::CameraModel& camera, const std::vector<TrackedPoint>& kept,
                       const Pose& a_w0_from_cam, const Pose& b_w0_from_cam) const;
  Outcome Relocalise(const processing::CameraModel& camera, const processing::StageFrame& frame,
                     const processing::TfSampler* sampler, const CameraState& state) const;
  // PnP on the map points `found` (TF positions, virtual depths v), then the
  // pose checks (against `predicted` when given) and at least min_inliers;
  // the inliers kept as they were found (templates, anchored). `what`
  // begins a failure's status.
  Outcome Solve(const processing::CameraModel& camera, const processing::TfSampler& sampler,
                const std::vector<TrackedPoint>& found, const std::vector<double>& v,
                const std::optional<Pose>& predicted, const std::string& what,
                int min_inliers) const;
  // Guided matching (guided_matches.h, `options`) from the pose `guide`, PnP
  // on the matches, the pose checks (against `guide` when check_jump) and at
  // least min_inliers: every inlier anchored. Re-anchoring (options_.guided,
  // from the tracked pose, checked against it) and the correction of a
  // prediction (options_.coarse, LocalizerOptions::correct_predictions, not
  // checked against the prediction it corrects).
  Outcome GuidedSolve(const processing::CameraModel& camera, const processing::TfSampler& sampler,
                      const ConstImageView& raw, const Pose& guide,
                      const GuidedMatchOptions& options, bool check_jump, const std::string& what,
                      int min_inliers) const;
  // The tracked inliers' offsets updated against the absolute pose
  // w0_from_anchor (TrackedPoint::offset, average_anchors), then Solve on
  // the corrected positions, checked against w0_from_anchor.
  Outcome AverageAnchor(const processing::CameraModel& camera,
                        const processing::TfSampler& sampler, const Outcome& tracked,
                        const Pose& w0_from_anchor) const;
  // Tracks for the next frame: `kept` (their templates kept when they have
  // one, else made at their projections from w0_from_cam) and map points in
  // cells with room, from pose w0_from_cam (anchored when `relocalised`,
  // offset weight new_weight: the anchors the pose averages); with
  // !next_has_velocity new templates get the extra level Track needs then.
  std::shared_ptr<const Tracks> Retrack(const processing::CameraModel& camera,
                                        const processing::TfSampler& sampler,
                                        const ConstImageView& raw, const Pose& w0_from_cam,
                                        const std::vector<TrackedPoint>& kept,
                                        bool relocalised, bool next_has_velocity,
                                        double new_weight) const;

  MapIndex map_;
  double map_virtual_depth_ = 3.0;  // median v of the map's keypoints (relocalisation's TF)
  ExtrinsicsRelater relater_;       // Relate's thread only
  LocalizerOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable done_cv_;  // a frame or a relocalisation ended (wait_for_earlier_frames)
  std::map<std::string, std::multiset<std::int64_t>> in_flight_;  // triggers, per camera
  std::map<std::string, CameraState> cameras_;
  // Per camera, kept across relocalisations (LocalizerOptions::min_far_track_success).
  struct FarTracking {
    double success = 1;  // running rate of the far frames tracked
    long long skipped = 0;  // far frames relocalised without an attempt (probes counted)
  };
  std::map<std::string, FarTracking> far_;
  Counts counts_;
};

// Localizer covariance (pose_covariance.h) -> the stage's convention (comment above).
Covariance6 ToLeftPerturbationCovariance(const PoseWithCovariance& pose);

}  // namespace lifmcr::registration
