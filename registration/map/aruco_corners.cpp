#include "registration/map/aruco_corners.h"

#include "config/decimal_number.h"
#include "config/text_escape.h"
#include "replay/csv_tokenizer.h"

#include <Eigen/Dense>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>

namespace lifmcr::registration {
namespace {

constexpr const char* kHeader = "frame,marker_id,corner,tf_x_px,tf_y_px,virtual_depth";
constexpr int kMarkers = 4;  // the plate's ids 0..3
// Ranges of the columns: frames a double counts exactly (2^53), ids of the
// largest ArUco dictionary (DICT_ARUCO_ORIGINAL, 1024 markers), TF pixel
// coordinates and virtual depths far beyond any sensor's (they keep a
// written row short, FormatArucoCornersCsv).
constexpr double kMaxFrame = 9007199254740991.0;
constexpr double kMaxMarkerId = 1023;
constexpr double kMaxCoordinate = 1e5;

}  // namespace

std::string FormatArucoCornersCsv(const std::vector<ArucoCornerObservation>& observations) {
  std::string text = std::string(kHeader) + "\n";
  for (const ArucoCornerObservation& o : observations) {
    char row[200];
    if (std::isnan(o.virtual_depth))
      std::snprintf(row, sizeof(row), "%lld,%d,%d,%.4f,%.4f,\n", static_cast<long long>(o.frame),
                    o.marker_id, o.corner, o.tf_px.x(), o.tf_px.y());
    else
      std::snprintf(row, sizeof(row), "%lld,%d,%d,%.4f,%.4f,%.5f\n",
                    static_cast<long long>(o.frame), o.marker_id, o.corner, o.tf_px.x(),
                    o.tf_px.y(), o.virtual_depth);
    text += row;
  }
  return text;
}

Expected<std::vector<ArucoCornerObservation>> ReadArucoCornersCsv(
    const std::filesystem::path& path) {
  Expected<std::vector<CsvRow>> rows =
      ReadHeadedCsv(path, kHeader, "an ArUco corners CSV (aruco_corners.csv)", 64ull << 20);
  if (!rows) return rows.error();
  std::vector<ArucoCornerObservation> out;
  for (const CsvRow& row : *rows) {
    if (row.fields.size() != 6)
      return MakeError(path.string(), row.line, 1,
                       "expected 6 fields (" + std::string(kHeader) + "), got " +
                           std::to_string(row.fields.size()));
    double v[6];
    for (int k = 0; k < 6; ++k) {
      const std::string& t = row.fields[k].text;
      if (k == 5 && t.empty()) {
        v[k] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      const auto [p, ec] = FromCharsRounded(t.data(), t.data() + t.size(), v[k]);
      if (ec != std::errc() || p != t.data() + t.size() || !std::isfinite(v[k]))
        return MakeError(path.string(), row.line, row.fields[k].column,
                         "expected a number, got '" + Excerpt(t) + "'");
    }
    // Checked before the casts (a double out of an int's range is undefined
    // behaviour to convert).
    auto integer_in = [](double x, double lo, double hi) {
      return x == std::floor(x) && x >= lo && x <= hi;
    };
    if (!integer_in(v[0], 0, kMaxFrame) || !integer_in(v[1], 0, kMaxMarkerId) ||
        !integer_in(v[2], 0, 3))
      return MakeError(path.string(), row.line, 1,
                       "expected an integer frame >= 0, a marker id 0.." +
                           std::to_string(static_cast<int>(kMaxMarkerId)) + " and a corner 0..3");
    for (int k = 3; k < 6; ++k) {
      if (std::abs(v[k]) > kMaxCoordinate)
        return MakeError(path.string(), row.line, row.fields[k].column,
                         "expected a TF coordinate or virtual depth within 1e5");
    }
    ArucoCornerObservation o;
    o.frame = static_cast<std::int64_t>(v[0]);
    o.marker_id = static_cast<int>(v[1]);
    o.corner = static_cast<int>(v[2]);
    o.tf_px = Eigen::Vector2d(v[3], v[4]);
    o.virtual_depth = v[5];
    out.push_back(o);
  }
  return out;
}

std::string ArucoCentersInMap::BriefReport() const {
  char line[200];
  std::snprintf(line, sizeof(line),
                "ArUco centres from %d corners (%d rays in %d frames), rays %.2f mm RMS from their "
                "corners",
                corners, observations, frames, ray_rms_mm);
  return line;
}

Expected<ArucoCentersInMap> TriangulateArucoCenters(
    const std::vector<ArucoCornerObservation>& observations,
    const std::map<std::int64_t, Pose>& w0_from_c0, const processing::CameraModel& camera) {
  struct Ray {
    Eigen::Vector3d origin, direction;
  };
  std::map<std::pair<int, int>, std::vector<Ray>> rays;  // (id, corner) -> rays in the map
  std::set<std::int64_t> frames;
  for (const ArucoCornerObservation& o : observations) {
    if (o.marker_id >= kMarkers || std::isnan(o.virtual_depth) || !(o.virtual_depth > 1)) continue;
    const auto pose = w0_from_c0.find(o.frame);
    if (pose == w0_from_c0.end()) continue;
    const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(o.tf_px);
    const Eigen::Vector3d p_in_c0 = camera.BackProject(Eigen::Vector3d(raw.x(), raw.y(), o.virtual_depth));
    if (!p_in_c0.allFinite() || !(p_in_c0.z() > 0)) continue;
    rays[{o.marker_id, o.corner}].push_back(
        {pose->second.translation(), pose->second.linear() * p_in_c0.normalized()});
    frames.insert(o.frame);
  }
  ArucoCentersInMap out;
  out.frames = static_cast<int>(frames.size());
  double sum_sq = 0;
  for (int id = 0; id < kMarkers; ++id) {
    Eigen::Vector3d center = Eigen::Vector3d::Zero();
    for (int corner = 0; corner < 4; ++corner) {
      const std::vector<Ray>& r = rays[{id, corner}];
      const std::string which =
          "ArUco marker " + std::to_string(id) + " corner " + std::to_string(corner);
      if (r.size() < 2)
        return Error{which + ": seen with a virtual depth in " + std::to_string(r.size()) +
                     " placed frame(s); triangulation needs two"};
      Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      for (const Ray& ray : r) {
        const Eigen::Matrix3d m = Eigen::Matrix3d::Identity() - ray.direction * ray.direction.transpose();
        a += m;
        b += m * ray.origin;
      }
      // Parallel rays leave a near-singular normal matrix: its smallest
      // eigenvalue is the spread of directions (sin^2 of the angles).
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(a);
      if (!(eigen.eigenvalues()(0) > 1e-6 * static_cast<double>(r.size())))
        return Error{which + ": its rays are parallel (the frames see it from one direction)"};
      const Eigen::Vector3d p = a.ldlt().solve(b);
      for (const Ray& ray : r) {
        const Eigen::Vector3d off = p - ray.origin;
        sum_sq += (off - ray.direction * ray.direction.dot(off)).squaredNorm();
      }
      out.observations += static_cast<int>(r.size());
      ++out.corners;
      center += p / 4.0;
    }
    out.centers_mm[id] = center;
  }
  out.ray_rms_mm = std::sqrt(sum_sq / out.observations);
  return out;
}

}  // namespace lifmcr::registration
