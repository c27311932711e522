#include "config/frames.h"

#include <array>
#include <cmath>

namespace lifmcr {
namespace {

constexpr std::array<std::pair<RotationRepresentation, std::string_view>, 4> kRotationNames{{
    {RotationRepresentation::kHelicalRad, "helical_rad"},
    {RotationRepresentation::kHelicalDeg, "helical_deg"},
    {RotationRepresentation::kEulerXyzDeg, "euler_xyz_deg"},
    {RotationRepresentation::kEulerXyzRad, "euler_xyz_rad"},
}};

constexpr std::array<std::pair<Handedness, std::string_view>, 4> kHandednessNames{{
    {Handedness::kRight, "right"},
    {Handedness::kLeftFlipX, "left_flip_x"},
    {Handedness::kLeftFlipY, "left_flip_y"},
    {Handedness::kLeftFlipZ, "left_flip_z"},
}};

constexpr double kDegToRad = M_PI / 180.0;

Eigen::Matrix3d FromAxisAngleVector(const Eigen::Vector3d& r) {
  const double angle = r.norm();
  if (angle < 1e-12) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
}

}  // namespace

std::optional<RotationRepresentation> ParseRotationRepresentation(std::string_view name) {
  for (const auto& [value, text] : kRotationNames)
    if (text == name) return value;
  return std::nullopt;
}

std::string_view ToString(RotationRepresentation representation) {
  for (const auto& [value, text] : kRotationNames)
    if (value == representation) return text;
  return "?";
}

std::string RotationRepresentationNames() {
  std::string names;
  for (const auto& [value, text] : kRotationNames) {
    if (!names.empty()) names += "|";
    names += text;
  }
  return names;
}

Eigen::Matrix3d RotationFromVicon(RotationRepresentation representation, const Eigen::Vector3d& r) {
  switch (representation) {
    case RotationRepresentation::kHelicalRad:
      return FromAxisAngleVector(r);
    case RotationRepresentation::kHelicalDeg:
      return FromAxisAngleVector(r * kDegToRad);
    case RotationRepresentation::kEulerXyzDeg:
    case RotationRepresentation::kEulerXyzRad: {
      const Eigen::Vector3d a = representation == RotationRepresentation::kEulerXyzDeg
                                    ? Eigen::Vector3d(r * kDegToRad)
                                    : r;
      return (Eigen::AngleAxisd(a.x(), Eigen::Vector3d::UnitX()) *
              Eigen::AngleAxisd(a.y(), Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(a.z(), Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
    }
  }
  return Eigen::Matrix3d::Identity();
}

Eigen::Vector3d RotationToVicon(RotationRepresentation representation,
                                const Eigen::Matrix3d& rotation) {
  switch (representation) {
    case RotationRepresentation::kHelicalRad:
    case RotationRepresentation::kHelicalDeg: {
      const Eigen::AngleAxisd aa(rotation);
      const Eigen::Vector3d r = aa.axis() * aa.angle();
      return representation == RotationRepresentation::kHelicalDeg ? Eigen::Vector3d(r / kDegToRad)
                                                                   : r;
    }
    case RotationRepresentation::kEulerXyzDeg:
    case RotationRepresentation::kEulerXyzRad: {
      // R = Rx(a) Ry(b) Rz(c): R(0,2) = sin b, R(1,2) = -sin a cos b, R(0,1) = -cos b sin c.
      const double b = std::asin(std::clamp(rotation(0, 2), -1.0, 1.0));
      const double a = std::atan2(-rotation(1, 2), rotation(2, 2));
      const double c = std::atan2(-rotation(0, 1), rotation(0, 0));
      const Eigen::Vector3d r(a, b, c);
      return representation == RotationRepresentation::kEulerXyzDeg ? Eigen::Vector3d(r / kDegToRad)
                                                                    : r;
    }
  }
  return Eigen::Vector3d::Zero();
}

std::optional<Handedness> ParseHandedness(std::string_view name) {
  for (const auto& [value, text] : kHandednessNames)
    if (text == name) return value;
  return std::nullopt;
}

std::string_view ToString(Handedness handedness) {
  for (const auto& [value, text] : kHandednessNames)
    if (value == handedness) return text;
  return "?";
}

Eigen::Matrix3d ReflectionOf(Handedness handedness) {
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  switch (handedness) {
    case Handedness::kRight:
      break;
    case Handedness::kLeftFlipX:
      s(0, 0) = -1;
      break;
    case Handedness::kLeftFlipY:
      s(1, 1) = -1;
      break;
    case Handedness::kLeftFlipZ:
      s(2, 2) = -1;
      break;
  }
  return s;
}

Expected<Pose> ViconToRightHanded(Handedness handedness, const Eigen::Matrix3d& rotation,
                                  const Eigen::Vector3d& translation_mm, double tolerance) {
  const Eigen::Matrix3d s = ReflectionOf(handedness);
  const Eigen::Matrix3d r = s * rotation * s;
  const double det = r.determinant();
  const double orthogonality = (r.transpose() * r - Eigen::Matrix3d::Identity()).norm();
  if (!std::isfinite(det) || std::abs(det - 1.0) > tolerance || orthogonality > tolerance) {
    return Error{"not a rotation after handedness conversion (" +
                 std::string(ToString(handedness)) + "): det = " + std::to_string(det) +
                 ", |R^T R - I| = " + std::to_string(orthogonality)};
  }
  Pose pose = Pose::Identity();
  pose.linear() = r;
  pose.translation() = s * translation_mm;
  return pose;
}

void RightHandedToVicon(Handedness handedness, const Pose& pose, Eigen::Matrix3d* rotation,
                        Eigen::Vector3d* translation_mm) {
  const Eigen::Matrix3d s = ReflectionOf(handedness);
  *rotation = s * pose.linear() * s;
  *translation_mm = s * pose.translation();
}

}  // namespace lifmcr
