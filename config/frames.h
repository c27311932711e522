#pragma once
// Every frame and convention of lifmcr, stated once.
//
// Transforms follow the paper: H^{A}_{B} maps coordinates of frame B into
// frame A. Code names it `a_from_b` and stores it as Eigen::Isometry3d:
//   p_in_a = a_from_b * p_in_b,   a_from_c = a_from_b * b_from_c.
// Frames used across lifmcr:
//   c0, cx       camera frames (optical centre, x right, y down, z along the
//                optical axis), camera 0 is the reference of the rig.
//   w0, wx       the point-cloud (calibration) frame of camera 0 / camera X.
//   world        the marker plate: origin at its bottom-left Vicon marker,
//                x along the table, y across it, z up (paper, Ground Truth).
//   vicon        the Vicon system frame after conversion to right-handed.
//   marker       the origin of a Vicon object: the centroid of its markers.
// So the paper's H^{C0}_{CX} is `c0_from_cx`, a Vicon sample of camera 0 is
// `vicon_from_marker`, and the hand-eye offset is `marker_from_cam`.
//
// Units: millimetres for translations in files and on the wire, radians in
// code, pixels for image geometry; virtual depth has no unit.
//
// Vicon handedness: the paper records Vicon in a left-handed frame. lifmcr
// converts it once, when a Vicon pose is parsed, with a reflection S (one
// axis negated, det S = -1) applied to both sides of the rigid motion:
//   R_rh = S R_lh S,  t_rh = S t_lh.
// The result must have det R = +1; a rotation that is not a rotation is an
// error, never silently fixed.

#include "config/error.h"

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <string_view>

namespace lifmcr {

using Pose = Eigen::Isometry3d;

// How a Vicon export writes RX, RY, RZ. The file does not say; the rig file does.
enum class RotationRepresentation {
  kHelicalRad,   // axis * angle, angle in radians (Tracker's default export)
  kHelicalDeg,   // axis * angle, angle in degrees
  kEulerXyzDeg,  // R = Rx(rx) * Ry(ry) * Rz(rz), degrees (DataStream SDK "EulerXYZ")
  kEulerXyzRad,  // same, radians
};

// Names as written in rig files and on the command line: helical_rad,
// helical_deg, euler_xyz_deg, euler_xyz_rad.
std::optional<RotationRepresentation> ParseRotationRepresentation(std::string_view name);
std::string_view ToString(RotationRepresentation representation);
std::string RotationRepresentationNames();  // "helical_rad|helical_deg|..."

// Rotation (object to Vicon frame) from the three RX RY RZ columns.
Eigen::Matrix3d RotationFromVicon(RotationRepresentation representation, const Eigen::Vector3d& r);
// The inverse, used by writers (synthetic Vicon exports).
Eigen::Vector3d RotationToVicon(RotationRepresentation representation,
                                const Eigen::Matrix3d& rotation);

// Which axis a left-handed Vicon frame has mirrored relative to ours.
enum class Handedness { kRight, kLeftFlipX, kLeftFlipY, kLeftFlipZ };
std::optional<Handedness> ParseHandedness(
    std::string_view name);  // right|left_flip_x|left_flip_y|left_flip_z
std::string_view ToString(Handedness handedness);

// S of the comment above (identity for kRight).
Eigen::Matrix3d ReflectionOf(Handedness handedness);

// Converts a Vicon sample (rotation and translation in the Vicon file's
// frame) to a right-handed pose; an error when the result is not a proper
// rotation (|det - 1| or orthogonality off by more than `tolerance`).
Expected<Pose> ViconToRightHanded(Handedness handedness, const Eigen::Matrix3d& rotation,
                                  const Eigen::Vector3d& translation_mm, double tolerance = 1e-6);
// The inverse: a right-handed pose as the Vicon file would write it.
void RightHandedToVicon(Handedness handedness, const Pose& pose, Eigen::Matrix3d* rotation,
                        Eigen::Vector3d* translation_mm);

}  // namespace lifmcr
