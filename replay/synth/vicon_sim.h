#pragma once
// The Vicon of the synthetic rig. It samples every camera's marker cluster
// (and the marker plate) at rate_hz; the cameras are triggered on every
// trigger_divider-th Vicon frame from first_trigger_frame on, so image frame
// n (0-based) is Vicon frame first_trigger_frame + n * trigger_divider, the
// mapping replay/sequence.h assumes.
//
// Frames: the Vicon room frame `vicon` (right-handed here; the CSV writer
// mirrors it to the left-handed frame LiFMCR's exports use), the plate frame
// `world` placed in the room by vicon_from_world, and per camera the marker
// cluster frame `marker` (origin at the centroid of its four markers, as
// Tracker defines an object) offset from the optical centre by the rigid
// marker_from_cam:
//   vicon_from_marker(t) = vicon_from_world * world_from_cam(t) * inverse(marker_from_cam).
// Noise: every marker position gets isotropic Gaussian noise of
// marker_noise_mm; the reported pose is the rigid fit (Umeyama, no scale) of
// the cluster model to the noisy markers, as a motion-capture system does.

#include "config/frames.h"
#include "replay/synth/synth_params.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::synth {

struct MarkerCluster {
  std::string subject;                        // Vicon object name, e.g. "cam0"
  std::array<Eigen::Vector3d, 4> markers_mm;  // in the cluster frame, centroid 0
};

// A camera's cluster: four markers, asymmetric (unique identification), on a
// plate of about 100 x 60 mm; and its realistic offset from the optical centre:
// a few tens of mm (above and behind the lens) and a few degrees.
MarkerCluster MakeCameraCluster(const std::string& subject, std::uint64_t seed);
Pose MakeMarkerFromCam(std::uint64_t seed);
// The plate's cluster: its four corner markers, centred on their centroid;
// world_from_plate_marker is then a pure translation to that centroid.
MarkerCluster MakePlateCluster(const std::string& subject,
                               const std::array<Eigen::Vector3d, 4>& corners_in_world,
                               Pose* world_from_plate_marker);
// Where the plate lies in the Vicon room (a fixed, generic placement).
Pose DefaultViconFromWorld();

struct ViconTrack {
  std::string subject;
  std::vector<std::int64_t> frames;                    // Vicon frame numbers
  std::vector<std::optional<Pose>> vicon_from_marker;  // nullopt in occlusion gaps
};

// The noisy pose of a cluster whose true pose is `vicon_from_marker`.
Pose ObserveCluster(const MarkerCluster& cluster, const Pose& vicon_from_marker, double noise_mm,
                    std::uint64_t seed, std::uint64_t index);

// Vicon frame of image frame n.
std::int64_t ViconFrameOfImage(const SynthViconParams& vicon, std::int64_t image_frame);
// Time (s) of a Vicon frame, 0 at the first trigger.
double TimeOfViconFrame(const SynthViconParams& vicon, std::int64_t vicon_frame);
// Vicon frames recorded for `image_frames` triggers: from max(1, first trigger -
// lead-in) to the last trigger + divider - 1.
std::vector<std::int64_t> RecordedViconFrames(const SynthViconParams& vicon, int image_frames);

// Occlusion gaps: `gaps` runs of `length` frames at seeded places, as a set
// of frame indices (into `frame_count`) to blank.
std::vector<bool> OcclusionMask(int frame_count, int gaps, int length, std::uint64_t seed);

}  // namespace lifmcr::synth
