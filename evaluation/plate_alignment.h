#pragma once
// Alignment of the map (point-cloud) frame with the Vicon frame through the
// marker plate, as the paper's supplementary ("Data Alignment for the
// evaluation") describes.
//
// The plate carries four ArUco markers (ids 0..3) and four Vicon markers; a
// template gives both in the plate frame `world` (origin at the bottom-left
// Vicon marker, config/frames.h). Two chains meet in `world`:
//
//  Map side (ArUco). The centres P_0..P_3 of the ArUco markers seen in the
//  map frame define a local frame: origin P_2, x = (P_3 - P_2)/|.|,
//  y = (P_0 - P_2)/|.|, z = x × y / |.|, then y <- z × x (so that the axes
//  are orthonormal; the paper writes the re-orthogonalisation on z, which
//  leaves x and y non-orthogonal when the detections are). P_1 is the check:
//  R^T (P_1 - P_2) against the same quantity on the template, its distance is
//  the "aruco check" residual. The same construction on the template gives
//  world_from_aruco; so world_from_map = world_from_aruco · (map_from_aruco)^-1:
//  the paper's "translation between the lower-left Vicon marker and the
//  lower-left ArUco marker", with the rotation included.
//
//  Vicon side. The plate's Vicon object gives vicon_from_plate (its marker
//  centroid frame) per sample; the VSK gives its markers in that frame. The
//  rigid fit (Umeyama) of the VSK markers onto the template's Vicon markers,
//  over the 24 orderings (marker names need not follow the template), gives
//  world_from_plate and the "marker fit" residual (RMS, mm). With the plate
//  at rest, vicon_from_plate is averaged over the samples (chordal mean of
//  the rotations, mean of the translations); the RMS deviation of its
//  markers from where the mean pose puts them says whether the plate moved
//  (the largest deviation is reported too, but it grows with the number of
//  samples: 0.3 mm marker noise reaches 1 mm somewhere in a few thousand).
//
//   vicon_from_map = vicon_from_plate · (world_from_plate)^-1 · world_from_map.

#include "config/error.h"
#include "config/frames.h"
#include "replay/vicon_poses.h"

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string>

namespace lifmcr {

struct PlateTemplate {
  std::array<Eigen::Vector3d, 4> aruco_centers_mm;  // ids 0..3, plate frame
  std::array<Eigen::Vector3d, 4> vicon_markers_mm;  // plate frame, any order
};

// The plate `lifmcr synth` draws (replay/synth/marker_plate.h).
PlateTemplate DefaultPlateTemplate();

struct ArucoPlateFrame {
  Pose frame_from_aruco;  // the local frame of the supplementary in the detections' frame
  double check_mm = 0;    // P_1 residual
};

// The construction above on four centres (ids 0..3). Error when the three
// points P_2, P_3, P_0 are (nearly) collinear.
Expected<ArucoPlateFrame> ArucoFrameOf(const std::array<Eigen::Vector3d, 4>& centers_mm,
                                       const PlateTemplate& plate);

struct PlateAlignment {
  Pose vicon_from_world = Pose::Identity();
  Pose world_from_map = Pose::Identity();
  double aruco_check_mm = 0;     // P_1 residual of the map's detections
  double marker_fit_rms_mm = 0;  // VSK markers vs template
  // Deviation of the plate's markers from the mean pose over the samples:
  // RMS over samples and markers (the motion check), and the largest.
  double plate_motion_rms_mm = 0;
  double plate_motion_rms_deg = 0;  // RMS rotation angle from the mean
  double plate_motion_max_mm = 0;
  double plate_motion_max_deg = 0;
  std::size_t plate_samples = 0;
  bool map_is_plate_frame = true;  // no detections given: the map frame is the plate frame

  // Above this RMS marker deviation the plate counts as moved.
  static constexpr double kMovedRmsMm = 1.0;
  bool plate_moved() const { return plate_motion_rms_mm > kMovedRmsMm; }

  Pose vicon_from_map() const { return vicon_from_world * world_from_map; }
  // "plate alignment: Vicon markers fit the template to 0.120 mm RMS, ..., plate still (RMS
  // deviation 0.21 mm / 0.02 deg, largest 0.9 mm / 0.08 deg over 1600 samples)"
  std::string BriefReport() const;
};

// `plate_samples`: the plate object's Vicon samples; `plate_markers_mm`: its
// VSK markers (4); `aruco_in_map_mm`: the ArUco centres seen in the map frame,
// none when the map is already the plate frame (lifmcr calibrate defines it
// so). Errors: no tracked sample, not 4 markers, a degenerate plate.
Expected<PlateAlignment> AlignPlate(std::span<const ViconPoseSample> plate_samples,
                                    std::span<const Eigen::Vector3d> plate_markers_mm,
                                    const PlateTemplate& plate,
                                    const std::optional<std::array<Eigen::Vector3d, 4>>& aruco_in_map_mm);

}  // namespace lifmcr
