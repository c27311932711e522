#pragma once
// Ground truth for camera frames from a Vicon export: each camera's Vicon
// object pose (vicon_from_marker, right-handed, mm) at each image frame.
//
// Association by trigger (replay/sequence.h): the cameras fire on every
// trigger_divider-th Vicon frame, so image frame n was exposed at Vicon frame
//   v(n) = vicon_frame_of_first_trigger + trigger_divider (n - first_frame)
//          + vicon_frame_offset.
// An integer v(n) takes that sample; a fractional one (a known trigger
// latency given as vicon_frame_offset) interpolates the two samples around
// it in SE(3) (replay/vicon_interpolation.h). A frame whose samples are
// untracked (empty cells), missing, or further apart than max_gap_frames is
// counted and left out, never given a zero pose.

#include "config/error.h"
#include "config/frames.h"
#include "evaluation/trajectory_metrics.h"
#include "replay/vicon_poses.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

struct FrameAssociationOptions {
  int trigger_divider = 8;                        // Vicon frames per camera trigger, >= 1
  std::int64_t vicon_frame_of_first_trigger = 1;  // CSV frames are 1-based
  std::int64_t first_frame = 0;                   // image frame number of that trigger
  double vicon_frame_offset = 0;                  // added to v(n), may be fractional
  int max_gap_frames = 1;                         // largest Vicon gap to interpolate over, >= 1

  Status Check() const;
  // v(n) above.
  double ViconFrameOf(std::int64_t frame) const;
};

struct AssociatedPoses {
  FramePoses vicon_from_marker;              // per image frame with a pose
  std::vector<std::int64_t> untracked;       // frames asked for without one
};

// The pose of one subject's samples (sorted by Vicon frame, as
// ExtractSubjectPoses returns them) at each of `frames`.
AssociatedPoses AssociateFrames(std::span<const ViconPoseSample> samples,
                                std::span<const std::int64_t> frames,
                                const FrameAssociationOptions& options);

// Every image frame whose trigger lies within the samples: from the first
// to the last sample's Vicon frame.
std::vector<std::int64_t> FramesCoveredBy(std::span<const ViconPoseSample> samples,
                                          const FrameAssociationOptions& options);

}  // namespace lifmcr
