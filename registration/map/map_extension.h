#pragma once
// A reference map extended by the frames of cameras already registered to it:
// the cheap form of a map shared by a rig's cameras. A camera far from
// camera 0 sees little of camera 0's map but much of its neighbour's view, so
// registering the cameras in order and adding each registered camera's
// points lets the next one register through its neighbour (a chain: camera 3
// through camera 2's frames, camera 2 through camera 1's, camera 1 through
// camera 0's map).
//
// A new point must be seen twice. One plenoptic observation places a point
// along its ray only to the virtual depth's noise, which grows as (Z - f_L)^2
// (registration/estimators/plenoptic_point_noise.h: several mm at 1.8 m) and
// lies across the next camera's rays; two observations from viewpoints apart
// (the same trigger of two cameras of the rig, or neighbouring triggers of
// one) fix it to their rays' intersection. So:
//   1. each registered frame's keypoints that match no map point (ratio and
//      cross check against the map's kd-forest) and have a depth are kept
//      pending, back-projected by the frame's w0_from_cam with their
//      plenoptic covariance (plus pose_sigma_mm isotropic for the pose);
//   2. each is matched (ratio and cross check) against the pending keypoints
//      of the frames it pairs with: the same trigger of every other camera
//      and the neighbouring triggers of its own camera; a match joins two
//      tracks when the points agree, (p1 - p2)^T (S1 + S2)^-1 (p1 - p2) <=
//      agreement_chi2 (99 % of chi-square(3)), and the tracks share no frame;
//   3. a track of at least two observations (spanning min_cameras cameras)
//      becomes a map point: the
//      information-weighted mean (sum S_i^-1)^-1 sum S_i^-1 p_i, its sigma_mm
//      that covariance's diagonal, the descriptor of its observation by the
//      camera added last (the nearest view of the next camera).
// The points carry no track: the map's images stay camera 0's, so the map
// still reads as one COLMAP camera.
//
// The fusion assumes unbiased virtual depths. With exact depths (a
// synthetic rig's ground truth) the far camera of a 4-camera `small` rig
// registers through the chain where camera 0's map alone places none of its
// frames (docs/registration.md, "A rig of several cameras: the chained
// map"); processing/'s virtual depth is biased by 0.1-0.3 %
// (docs/calibration.md, "Known limits"), several mm along the ray at 1.8 m,
// and a neighbour's points placed from it carry that error to the next
// camera.

#include "config/error.h"
#include "config/frames.h"
#include "processing/camera_model.h"
#include "registration/features/features.h"
#include "registration/features/frame_observations.h"
#include "registration/map/frame_registration.h"
#include "registration/map/reference_map.h"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct MapExtensionOptions {
  MatchOptions map_match = MapMatching();     // keypoints against the map's kd-forest
  MatchOptions pair_match = ExactMatching();  // pending keypoints of two frames
  double sigma_v_relative = 0.007;            // virtual-depth noise / v, > 0
  double sigma_tf_px = 0.3;                   // keypoint noise (TF px), > 0
  double pose_sigma_mm = 0.5;                 // a registered pose's error at the point, >= 0
  double agreement_chi2 = 11.345;             // 99 % of chi-square(3), > 0
  int min_cameras = 1;                        // cameras a track's observations span, >= 1
  Status Check() const;                       // every field; the message names it
};

struct MapExtension {
  int pending = 0;    // keypoints kept pending
  int matched = 0;    // keypoints that matched a map point
  int no_depth = 0;   // keypoints without a virtual depth
  int joined = 0;     // pair matches that joined two tracks
  int disagreed = 0;  // pair matches whose points did not agree
  int added = 0;      // map points made
  // "3649 keypoints pending (2668 matched the map, 0 without depth), 1397
  // pairs joined, 115 disagreed: 707 points added".
  std::string BriefReport() const;
};

class SharedMapBuilder {
 public:
  explicit SharedMapBuilder(MapExtensionOptions options) : options_(std::move(options)) {}

  // Camera `camera_order` (0 for camera 0, then the order of registration)
  // frame registered at w0_from_cam; `map` is the index of the map now.
  // Errors: options, or a frame whose arrays differ in size.
  Status AddFrame(int camera_order, const processing::CameraModel& camera,
                  const FrameObservations& frame, const Pose& w0_from_cam, const MapIndex& map);
  // Every track of >= 2 observations not yet in `map` joins it; ids
  // continue after the map's largest. The report covers the frames added
  // since the last call.
  MapExtension AddTracksTo(ReferenceMap* map);

 private:
  struct Observation {
    Eigen::Vector3d p_in_w0_mm;
    Eigen::Matrix3d information;  // inverse covariance
    Eigen::Matrix3d covariance;
    int frame_slot = 0;  // index into frames_
    int descriptor = 0;  // row in its frame's descriptors
    int parent = 0;      // union-find
    bool emitted = false;
  };
  struct PendingFrame {
    int camera_order = 0;
    std::int64_t frame = 0;
    std::vector<float> descriptors;  // rows of its observations
    std::vector<int> observations;   // indices into observations_
  };
  int Root(int i);
  void Pair(int a, int b);  // frames_ slots

  MapExtensionOptions options_;
  std::vector<Observation> observations_;
  std::vector<PendingFrame> frames_;
  std::vector<std::vector<int>> track_frames_;  // per root: its frames' slots
  MapExtension report_;
};

}  // namespace lifmcr::registration
