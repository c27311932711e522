#include "registration/map/poses_csv.h"

#include "config/decimal_number.h"
#include "config/text_escape.h"
#include "replay/csv_tokenizer.h"

#include <Eigen/Geometry>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace lifmcr::registration {
namespace {

constexpr const char* kHeader = "frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz";
// Frame numbers are integers a double holds exactly (2^53); positions lie
// within 1 km of the origin (a Vicon volume is tens of metres).
constexpr double kMaxFrame = 9007199254740992.0;
constexpr double kMaxPositionMm = 1e6;

}  // namespace

std::string FormatPosesCsv(const std::vector<FramePose>& poses) {
  std::string text = std::string(kHeader) + "\n";
  for (const FramePose& p : poses) {
    const Eigen::Quaterniond q(p.world_from_cam.linear());
    const Eigen::Vector3d t = p.world_from_cam.translation();
    char row[320];
    std::snprintf(row, sizeof(row), "%lld,%lld,%.6f,%.6f,%.6f,%.12f,%.12f,%.12f,%.12f\n",
                  static_cast<long long>(p.frame), static_cast<long long>(p.vicon_frame), t.x(),
                  t.y(), t.z(), q.w(), q.x(), q.y(), q.z());
    text += row;
  }
  return text;
}

Status WritePosesCsv(const std::filesystem::path& path, const std::vector<FramePose>& poses) {
  std::ofstream out(path, std::ios::binary);
  out << FormatPosesCsv(poses);
  if (!out) return Error{path.string() + ": could not write"};
  return Status::Ok();
}

Expected<std::vector<FramePose>> ReadPosesCsv(const std::filesystem::path& path) {
  Expected<std::vector<CsvRow>> rows =
      ReadHeadedCsv(path, kHeader, "a camera poses CSV (poses_<serial>.csv)", 64ull << 20);
  if (!rows) return rows.error();
  std::vector<FramePose> poses;
  for (const CsvRow& row : *rows) {
    if (row.fields.size() != 9)
      return MakeError(path.string(), row.line, 1, "expected 9 fields, got " +
                                                       std::to_string(row.fields.size()));
    double v[9];
    for (int k = 0; k < 9; ++k) {
      const std::string& s = row.fields[k].text;
      const auto [end, ec] = FromCharsRounded(s.data(), s.data() + s.size(), v[k]);
      // from_chars also takes "inf" and "nan": neither is a pose.
      if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v[k]))
        return MakeError(path.string(), row.line, row.fields[k].column,
                         "expected a number, got '" + Excerpt(s) + "'");
    }
    if (v[0] != std::floor(v[0]) || v[0] < 0 || v[0] >= kMaxFrame)
      return MakeError(path.string(), row.line, row.fields[0].column,
                       "expected a frame number, an integer >= 0");
    if (v[1] != std::floor(v[1]) || v[1] < -1 || v[1] >= kMaxFrame)
      return MakeError(path.string(), row.line, row.fields[1].column,
                       "expected a Vicon frame number, an integer >= -1 (-1: unknown)");
    for (int k = 2; k < 5; ++k) {
      if (std::abs(v[k]) > kMaxPositionMm)
        return MakeError(path.string(), row.line, row.fields[k].column,
                         "expected a position within 1e6 mm (1 km) of the origin");
    }
    FramePose p;
    p.frame = static_cast<std::int64_t>(v[0]);
    p.vicon_frame = static_cast<std::int64_t>(v[1]);
    Eigen::Quaterniond q(v[5], v[6], v[7], v[8]);
    if (std::abs(q.norm() - 1.0) > 1e-3)
      return MakeError(path.string(), row.line, row.fields[5].column,
                       "expected a unit quaternion (qw, qx, qy, qz)");
    p.world_from_cam.linear() = q.normalized().toRotationMatrix();
    p.world_from_cam.translation() = Eigen::Vector3d(v[2], v[3], v[4]);
    poses.push_back(p);
  }
  return poses;
}

}  // namespace lifmcr::registration
