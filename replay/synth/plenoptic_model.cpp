#include "replay/synth/plenoptic_model.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <vector>

namespace lifmcr::synth {
namespace {

constexpr double kSqrt3Over2 = 0.86602540378443864676;

int Mod3(int x) { return ((x % 3) + 3) % 3; }

double Cos4(double tan_angle) {
  const double c2 = 1.0 / (1.0 + tan_angle * tan_angle);
  return c2 * c2;
}

}  // namespace

PlenopticModel::PlenopticModel(const SynthCameraParams& params) : p_(params) {
  principal_px_ = {(p_.width_px - 1) / 2.0, (p_.height_px - 1) / 2.0};
  MlaCalibration nominal;
  nominal.offset_px = p_.mla_offset_px;
  reference_px_ = nominal.ReferenceLensCenterPx(p_.width_px, p_.height_px);
  // Lattice steps in y-up coordinates, rotated counter-clockwise, then y flipped.
  const double c = std::cos(p_.mla_rotation_rad), s = std::sin(p_.mla_rotation_rad);
  Eigen::Matrix2d rotation;
  rotation << c, -s, s, c;
  Eigen::Matrix2d basis_up;
  basis_up << 1.0, 0.5, 0.0, kSqrt3Over2;
  Eigen::Matrix2d flip_y = Eigen::Vector2d(1, -1).asDiagonal();
  lattice_ = flip_y * rotation * basis_up * p_.micro_image_pitch_px;
  lattice_inv_ = lattice_.inverse();
  mla_tilt_ = (Eigen::AngleAxisd(p_.mla_tilt_x_rad, Eigen::Vector3d::UnitX()) *
               Eigen::AngleAxisd(p_.mla_tilt_y_rad, Eigen::Vector3d::UnitY()))
                  .toRotationMatrix();
  tilted_ = p_.mla_tilt_x_rad != 0.0 || p_.mla_tilt_y_rad != 0.0;
  has_distortion_ = p_.distortion_k1 != 0.0 || p_.distortion_k2 != 0.0 || p_.distortion_p1 != 0.0 ||
                    p_.distortion_p2 != 0.0;
}

double PlenopticModel::micro_lens_pitch_mm() const {
  const double b_l0 = p_.mla_to_main_lens_mm, b = p_.mla_to_sensor_mm;
  return p_.micro_image_pitch_px * p_.pixel_size_mm * b_l0 / (b_l0 + b);
}

double PlenopticModel::micro_image_disc_px() const {
  return aperture_mm() * p_.mla_to_sensor_mm / (p_.mla_to_main_lens_mm * p_.pixel_size_mm);
}

Eigen::Vector2d PlenopticModel::LatticeCenterPx(int i, int j) const {
  return reference_px_ + lattice_ * Eigen::Vector2d(i, j);
}

int PlenopticModel::LensType(int i, int j) { return Mod3(i - j); }

Eigen::Vector3d PlenopticModel::LensCenter3d(const Eigen::Vector2d& lattice_px) const {
  const double b_l0 = p_.mla_to_main_lens_mm, b = p_.mla_to_sensor_mm;
  const Eigen::Vector2d flat = (lattice_px - principal_px_) * p_.pixel_size_mm * b_l0 / (b_l0 + b);
  if (!tilted_) return {flat.x(), flat.y(), b_l0};
  return Eigen::Vector3d(0, 0, b_l0) + mla_tilt_ * Eigen::Vector3d(flat.x(), flat.y(), 0.0);
}

MicroLens PlenopticModel::Lens(int i, int j) const {
  MicroLens lens;
  lens.i = i;
  lens.j = j;
  lens.type = LensType(i, j);
  const Eigen::Vector2d lattice_px = LatticeCenterPx(i, j);
  lens.lens_mm = LensCenter3d(lattice_px);
  if (!tilted_) {
    lens.center_px = lattice_px;
  } else {
    // Seen from the main-lens centre onto the sensor plane.
    const double sensor_z = p_.mla_to_main_lens_mm + p_.mla_to_sensor_mm;
    const Eigen::Vector2d c_mm = lens.lens_mm.head<2>() * sensor_z / lens.lens_mm.z();
    lens.center_px = c_mm / p_.pixel_size_mm + principal_px_;
  }
  return lens;
}

void PlenopticModel::NearestLens(const Eigen::Vector2d& p_px, int* i, int* j) const {
  const Eigen::Vector2d axial = lattice_inv_ * (p_px - reference_px_);
  // Cube rounding of axial hex coordinates (q, r, s = -q - r).
  const double q = axial.x(), r = axial.y(), s = -q - r;
  double rq = std::round(q), rr = std::round(r), rs = std::round(s);
  const double dq = std::abs(rq - q), dr = std::abs(rr - r), ds = std::abs(rs - s);
  if (dq > dr && dq > ds)
    rq = -rr - rs;
  else if (dr > ds)
    rr = -rq - rs;
  *i = static_cast<int>(rq);
  *j = static_cast<int>(rr);
}

double PlenopticModel::ImageDistanceOfDepth(double z_mm) const {
  const double f = p_.main_focal_length_mm;
  return f * z_mm / (z_mm - f);
}

double PlenopticModel::VirtualDepthOfDepth(double z_mm) const {
  return (ImageDistanceOfDepth(z_mm) - p_.mla_to_main_lens_mm) / p_.mla_to_sensor_mm;
}

double PlenopticModel::DepthOfVirtualDepth(double v) const {
  const double b = p_.mla_to_main_lens_mm + v * p_.mla_to_sensor_mm;
  const double f = p_.main_focal_length_mm;
  return f * b / (b - f);
}

Eigen::Vector2d PlenopticModel::Distort(const Eigen::Vector2d& x) const {
  const double r2 = x.squaredNorm();
  const double radial = p_.distortion_k1 * r2 + p_.distortion_k2 * r2 * r2;
  const double p1 = p_.distortion_p1, p2 = p_.distortion_p2;
  return {x.x() + x.x() * radial + p1 * (r2 + 2 * x.x() * x.x()) + 2 * p2 * x.x() * x.y(),
          x.y() + x.y() * radial + p2 * (r2 + 2 * x.y() * x.y()) + 2 * p1 * x.x() * x.y()};
}

Eigen::Vector2d PlenopticModel::Undistort(const Eigen::Vector2d& x_d) const {
  // LiFCal's fixed point x <- x_d - delta(x), converged further for exactness.
  Eigen::Vector2d x = x_d;
  for (int k = 0; k < 20; ++k) x = x_d - (Distort(x) - x);
  return x;
}

Eigen::Vector3d PlenopticModel::VirtualPoint(const Eigen::Vector3d& p_in_cam) const {
  const double b = ImageDistanceOfDepth(p_in_cam.z());
  const double b_l0 = p_.mla_to_main_lens_mm;
  Eigen::Vector2d x_mla = p_in_cam.head<2>() * b_l0 / p_in_cam.z();
  if (has_distortion_) x_mla = Distort(x_mla);
  const Eigen::Vector2d x_px = x_mla * b / b_l0 / p_.pixel_size_mm + principal_px_;
  return {x_px.x(), x_px.y(), (b - b_l0) / p_.mla_to_sensor_mm};
}

Eigen::Vector2d PlenopticModel::ProjectThroughLens(const MicroLens& lens,
                                                   const Eigen::Vector3d& virtual_px) const {
  const double b_l0 = p_.mla_to_main_lens_mm, b = p_.mla_to_sensor_mm;
  const Eigen::Vector3d x_v((virtual_px.x() - principal_px_.x()) * p_.pixel_size_mm,
                            (virtual_px.y() - principal_px_.y()) * p_.pixel_size_mm,
                            b_l0 + virtual_px.z() * b);
  const Eigen::Vector3d& l = lens.lens_mm;
  const double t = (b_l0 + b - l.z()) / (x_v.z() - l.z());
  const Eigen::Vector2d p_mm = l.head<2>() + (x_v.head<2>() - l.head<2>()) * t;
  return p_mm / p_.pixel_size_mm + principal_px_;
}

Eigen::Vector3d PlenopticModel::SensorPoint(const Eigen::Vector2d& p_px) const {
  const Eigen::Vector2d x = (p_px - principal_px_) * p_.pixel_size_mm;
  return {x.x(), x.y(), p_.mla_to_main_lens_mm + p_.mla_to_sensor_mm};
}

std::optional<PixelSample> PlenopticModel::TraceRawPixel(const Eigen::Vector2d& p_px) const {
  int i = 0, j = 0;
  NearestLens(p_px, &i, &j);
  return TraceThroughLens(p_px, Lens(i, j));
}

std::optional<PixelSample> PlenopticModel::TraceThroughLens(const Eigen::Vector2d& p_px,
                                                            const MicroLens& lens) const {
  PixelSample sample;
  sample.lens = lens;
  sample.radius_px = (p_px - sample.lens.center_px).norm();
  const Eigen::Vector3d sensor = SensorPoint(p_px);
  const Eigen::Vector3d& l = sample.lens.lens_mm;
  const Eigen::Vector3d along = l - sensor;  // towards the main lens (z decreasing)
  const Eigen::Vector3d m = sensor + along * (sensor.z() / (sensor.z() - l.z()));
  // Aperture coverage: distance of M inside the aperture rim, in sensor pixels.
  const double lens_to_sensor = sensor.z() - l.z();
  const double px_per_aperture_mm = lens_to_sensor / (l.z() * p_.pixel_size_mm);
  const double inside_px = (aperture_mm() / 2 - m.head<2>().norm()) * px_per_aperture_mm;
  // The rim is the main-lens aperture seen out of focus through the micro lens
  // (it sits at v = -b_L0 / B): blur d |1 + B/b_L0 - B/f_t| / s. The full value
  // assumes a micro lens filling its whole cell; real micro images show a
  // narrower rim (dark gaps where three micro images meet), so it is capped
  // at D / 8.
  const double rim_blur_px =
      std::clamp(micro_lens_pitch_mm() / p_.pixel_size_mm *
                     std::abs(1.0 + lens_to_sensor / l.z() -
                              lens_to_sensor / p_.micro_lens_focal_mm[sample.lens.type]),
                 1.0, p_.micro_image_pitch_px / 8);
  const double coverage = std::clamp(0.5 + inside_px / rim_blur_px, 0.0, 1.0);
  if (coverage <= 0.0) return std::nullopt;
  // Natural falloff: cos^4 of the main lens's chief-ray angle at c_k, and
  // cos^4 of the angle from the micro-image centre. Assumption: the sensor's
  // pixel lenslets are shifted for the main-lens chief-ray angle, so the
  // falloff inside a micro image is symmetric about c_k.
  const double c_mm = (sample.lens.center_px - principal_px_).norm() * p_.pixel_size_mm;
  const double falloff =
      Cos4(c_mm / sensor.z()) * Cos4(sample.radius_px * p_.pixel_size_mm / lens_to_sensor);
  sample.coverage = coverage;
  sample.falloff = falloff;
  sample.weight = coverage * falloff;
  const double f = p_.main_focal_length_mm;
  const Eigen::Vector3d q = sensor + along * ((sensor.z() - f) / (sensor.z() - l.z()));
  // Image-side lateral coordinates are mirrored (upright image): the lens
  // point M of the image-side line is the object-side point -M.
  sample.ray.origin = {-m.x(), -m.y(), 0.0};
  sample.ray.direction = {q.x() / f, q.y() / f, 1.0};
  return sample;
}

Eigen::Vector3d PlenopticModel::RawLineAt(const PixelSample& sample, const Eigen::Vector2d& p_px,
                                          double b_mm) const {
  const Eigen::Vector3d sensor = SensorPoint(p_px);
  const Eigen::Vector3d& l = sample.lens.lens_mm;
  return sensor + (l - sensor) * ((sensor.z() - b_mm) / (sensor.z() - l.z()));
}

Eigen::Vector3d PlenopticModel::TfLineAt(const Eigen::Vector2d& tf_px, double b_mm) const {
  const Eigen::Vector2d raw = tf_px * 2.0 + Eigen::Vector2d(0.5, 0.5);
  const Eigen::Vector2d x = (raw - principal_px_) * p_.pixel_size_mm;
  return {x.x(), x.y(), b_mm};
}

Ray PlenopticModel::ObjectRayOfImagePoint(const Eigen::Vector3d& x_img) const {
  const double b_l0 = p_.mla_to_main_lens_mm;
  const Eigen::Vector2d x_u = Undistort(x_img.head<2>() * b_l0 / x_img.z());
  return {Eigen::Vector3d::Zero(), Eigen::Vector3d(x_u.x() / b_l0, x_u.y() / b_l0, 1.0)};
}

Ray PlenopticModel::TfPixelRay(const Eigen::Vector2d& tf_px) const {
  const double f = p_.main_focal_length_mm;
  const Eigen::Vector3d x = TfLineAt(tf_px, f);
  return {Eigen::Vector3d(0, 0, f), Eigen::Vector3d(x.x() / f, x.y() / f, 1.0)};
}

double PlenopticModel::BlurDiameterPx(int type, double v) const {
  const double b = p_.mla_to_sensor_mm;
  return micro_lens_pitch_mm() / p_.pixel_size_mm *
         std::abs(1.0 - 1.0 / v - b / p_.micro_lens_focal_mm[type]);
}

Eigen::Vector2d PlenopticModel::SharpRange(int type) const {
  const double centre = p_.mla_to_sensor_mm / p_.micro_lens_focal_mm[type];
  const double tau = p_.sharp_blur_px * p_.pixel_size_mm / micro_lens_pitch_mm();
  const double u_min = centre - tau, u_max = centre + tau;
  const double v_min = u_min <= 0.0 ? 1.0 : std::max(1.0, 1.0 / (1.0 - u_min));
  const double v_max = u_max >= 0.99 ? 100.0 : 1.0 / (1.0 - u_max);
  return {v_min, v_max};
}

double PlenopticModel::TotalCoveringPlane() const {
  return 2.0 * p_.micro_image_pitch_px / (micro_image_disc_px() - 2.0 * p_.lens_border_px);
}

MlaCalibration PlenopticModel::ToMlaCalibration() const {
  MlaCalibration mla;
  mla.offset_px = p_.mla_offset_px;
  mla.diameter_px = p_.micro_image_pitch_px;
  mla.rotation_rad = p_.mla_rotation_rad;
  if (tilted_) {
    // Least squares over all lenses in the image: c = o + [a -b; b a] g, with g
    // the unit lattice point in y-up coordinates, a = D cos, b = D sin.
    std::vector<Eigen::Vector2d> g_up, c_up;
    const int reach =
        static_cast<int>(2 + std::max(p_.width_px, p_.height_px) / p_.micro_image_pitch_px * 1.3);
    for (int j = -reach; j <= reach; ++j)
      for (int i = -2 * reach; i <= 2 * reach; ++i) {
        const MicroLens lens = Lens(i, j);
        const Eigen::Vector2d c = lens.center_px;
        if (c.x() < 0 || c.y() < 0 || c.x() > p_.width_px - 1 || c.y() > p_.height_px - 1) continue;
        g_up.emplace_back(i + 0.5 * j, kSqrt3Over2 * j);
        c_up.emplace_back(c.x() - principal_px_.x(), principal_px_.y() - c.y());
      }
    Eigen::MatrixXd a(2 * g_up.size(), 4);
    Eigen::VectorXd rhs(2 * g_up.size());
    for (std::size_t k = 0; k < g_up.size(); ++k) {
      a.row(2 * k) << 1, 0, g_up[k].x(), -g_up[k].y();
      a.row(2 * k + 1) << 0, 1, g_up[k].y(), g_up[k].x();
      rhs(2 * k) = c_up[k].x();
      rhs(2 * k + 1) = c_up[k].y();
    }
    const Eigen::Vector4d x = a.colPivHouseholderQr().solve(rhs);
    mla.offset_px = x.head<2>();
    mla.diameter_px = std::hypot(x(2), x(3));
    mla.rotation_rad = std::atan2(x(3), x(2));
  }
  mla.lens_border_px = p_.lens_border_px;
  mla.tcp_virtual_depth = TotalCoveringPlane();
  // Types at +lens_base_x (id 1) and -lens_base_x (id 2), as the real R42 file.
  const std::array<Eigen::Vector2d, 3> offsets{Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0),
                                               Eigen::Vector2d(-1, 0)};
  for (int t = 0; t < 3; ++t) {
    mla.lens_types[t].id = t;
    mla.lens_types[t].offset_lens = offsets[t];
    const Eigen::Vector2d range = SharpRange(t);
    mla.lens_types[t].depth_min = range.x();
    mla.lens_types[t].depth_max = range.y();
  }
  // RxLive's own distortion model is not LiFCal's; the main-lens distortion
  // is ground truth in cameras.yaml, and the MLA file says "constant" as the
  // LiFMCR-style files do.
  mla.distortion.function = "constant";
  mla.distortion.parameters.clear();
  return mla;
}

}  // namespace lifmcr::synth
