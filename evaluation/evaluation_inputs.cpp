#include "evaluation/evaluation_inputs.h"

#include "config/decimal_number.h"
#include "config/yaml_reader.h"
#include "replay/csv_tokenizer.h"

#include <Eigen/Geometry>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace lifmcr {
namespace {

Expected<std::string> ReadText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeErrorAt(path.string(), "/", "cannot open the file");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Header name -> column index of a CSV document's first row.
struct CsvTable {
  std::string label;
  CsvDocument doc;
  std::map<std::string, std::size_t> column;

  Status Require(const std::vector<std::string>& names) const {
    for (const std::string& name : names)
      if (!column.count(name))
        return MakeError(label, doc.rows.empty() ? 1 : doc.rows[0].line, 0,
                         "the header lacks the column '" + name + "'");
    return Status::Ok();
  }
  const CsvField* Field(const CsvRow& row, const std::string& name) const {
    const auto it = column.find(name);
    if (it == column.end() || it->second >= row.fields.size()) return nullptr;
    return &row.fields[it->second];
  }
  Expected<double> Number(const CsvRow& row, const std::string& name) const {
    const CsvField* f = Field(row, name);
    if (!f) return MakeError(label, row.line, 0, "missing value of " + name);
    double v = 0;
    const char* begin = f->text.data();
    const char* end = begin + f->text.size();
    while (begin < end && *begin == ' ') ++begin;
    const auto [ptr, ec] = FromCharsRounded(begin, end, v);
    if (ec != std::errc() || ptr != end || !std::isfinite(v))
      return MakeError(label, f->line, f->column,
                       name + ": expected a finite number, got '" + f->text + "'");
    return v;
  }
  Expected<std::int64_t> Integer(const CsvRow& row, const std::string& name) const {
    const CsvField* f = Field(row, name);
    if (!f) return MakeError(label, row.line, 0, "missing value of " + name);
    std::int64_t v = 0;
    const auto [ptr, ec] = std::from_chars(f->text.data(), f->text.data() + f->text.size(), v);
    if (ec != std::errc() || ptr != f->text.data() + f->text.size())
      return MakeError(label, f->line, f->column,
                       name + ": expected an integer, got '" + f->text + "'");
    return v;
  }
  Expected<Pose> PoseAt(const CsvRow& row) const {
    double v[7];
    const char* names[7] = {"tx_mm", "ty_mm", "tz_mm", "qw", "qx", "qy", "qz"};
    for (int k = 0; k < 7; ++k) {
      Expected<double> x = Number(row, names[k]);
      if (!x) return x.error();
      v[k] = *x;
    }
    Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1.0) > 1e-3)
      return MakeError(label, row.line, 0,
                       "the quaternion (qw, qx, qy, qz) has norm " + std::to_string(q.norm()) +
                           ", expected 1");
    Pose pose = Pose::Identity();
    pose.linear() = q.normalized().toRotationMatrix();
    pose.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    return pose;
  }
};

Expected<CsvTable> ReadTable(const std::filesystem::path& path) {
  Expected<std::string> text = ReadText(path);
  if (!text) return text.error();
  Expected<CsvDocument> doc = TokenizeCsv(*text, path.string());
  if (!doc) return doc.error();
  CsvTable table;
  table.label = path.string();
  table.doc = std::move(*doc);
  if (table.doc.rows.empty()) return MakeErrorAt(path.string(), "/", "the file is empty");
  const CsvRow& header = table.doc.rows[0];
  for (std::size_t k = 0; k < header.fields.size(); ++k) {
    std::string name = header.fields[k].text;
    while (!name.empty() && name.front() == ' ') name.erase(name.begin());
    while (!name.empty() && (name.back() == ' ' || name.back() == '\r')) name.pop_back();
    table.column[name] = k;
  }
  return table;
}

std::string PoseFields(const Pose& pose) {
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d t = pose.translation();
  char text[256];
  std::snprintf(text, sizeof(text), "%.6f,%.6f,%.6f,%.12f,%.12f,%.12f,%.12f", t.x(), t.y(), t.z(),
                q.w(), q.x(), q.y(), q.z());
  return text;
}

void ReadPoseMap(YamlMap& map, Pose* pose) {
  double t[3] = {0, 0, 0}, q[4] = {1, 0, 0, 0};
  map.Read("tx_mm", &t[0], Presence::kRequired);
  map.Read("ty_mm", &t[1], Presence::kRequired);
  map.Read("tz_mm", &t[2], Presence::kRequired);
  map.Read("qw", &q[0], Presence::kRequired);
  map.Read("qx", &q[1], Presence::kRequired);
  map.Read("qy", &q[2], Presence::kRequired);
  map.Read("qz", &q[3], Presence::kRequired);
  const Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
  if (map.ok() && std::abs(quat.norm() - 1.0) > 1e-3)
    map.Fail(map.node(), "the quaternion (qw, qx, qy, qz) must have unit norm");
  *pose = Pose::Identity();
  if (quat.norm() > 0) pose->linear() = quat.normalized().toRotationMatrix();
  pose->translation() = Eigen::Vector3d(t[0], t[1], t[2]);
}

std::optional<Eigen::Vector3d> ReadPoint(YamlMap& map, const YamlNode& node) {
  const std::vector<YamlNode> e = node.Elements();
  if (e.size() != 3) {
    map.Fail(node, "expected [x, y, z] in mm, got " + node.Describe());
    return std::nullopt;
  }
  Eigen::Vector3d p;
  for (int k = 0; k < 3; ++k) {
    const auto [ptr, ec] = FromCharsRounded(e[k].Scalar().data(),
                                           e[k].Scalar().data() + e[k].Scalar().size(), p[k]);
    if (ec != std::errc() || ptr != e[k].Scalar().data() + e[k].Scalar().size()) {
      map.Fail(e[k], "expected a number, got " + e[k].Describe());
      return std::nullopt;
    }
  }
  return p;
}

}  // namespace

Expected<RegistrationTable> ReadRegistrationCsv(const std::filesystem::path& path) {
  Expected<CsvTable> table = ReadTable(path);
  if (!table) return table.error();
  if (Status s = table->Require({"frame", "camera", "method", "tx_mm", "ty_mm", "tz_mm", "qw",
                                 "qx", "qy", "qz", "status"});
      !s)
    return s.error();
  RegistrationTable result;
  result.path = path;
  for (std::size_t r = 1; r < table->doc.rows.size(); ++r) {
    const CsvRow& row = table->doc.rows[r];
    if (row.IsBlank()) continue;
    RegistrationRow out;
    out.line = row.line;
    Expected<std::int64_t> frame = table->Integer(row, "frame");
    if (!frame) return frame.error();
    out.frame = *frame;
    out.camera = table->Field(row, "camera")->text;
    out.method = table->Field(row, "method")->text;
    const CsvField* status = table->Field(row, "status");
    out.status = status ? status->text : "";
    if (out.camera.empty())
      return MakeError(path.string(), row.line, 0, "camera: expected a serial, got nothing");
    if (out.status == "ok") {
      Expected<Pose> pose = table->PoseAt(row);
      if (!pose) return pose.error();
      out.c0_from_cx = *pose;
      if (table->column.count("inliers")) {
        Expected<std::int64_t> inliers = table->Integer(row, "inliers");
        if (inliers) out.inliers = *inliers;
      }
      if (table->column.count("rmse_px")) {
        Expected<double> rmse = table->Number(row, "rmse_px");
        if (rmse) out.rmse_px = *rmse;
      }
    } else if (out.status.empty()) {
      out.status = "no status";
    }
    result.rows.push_back(std::move(out));
  }
  return result;
}

std::string FormatRegistrationCsv(const std::vector<RegistrationRow>& rows) {
  std::string text = "frame,camera,method,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz,inliers,rmse_px,status\n";
  for (const RegistrationRow& row : rows) {
    char tail[64];
    std::snprintf(tail, sizeof(tail), ",%lld,%.4f,", static_cast<long long>(row.inliers),
                  row.rmse_px);
    text += std::to_string(row.frame) + "," + FormatCsvField(row.camera, ',') + "," +
            FormatCsvField(row.method, ',') + "," +
            (row.status == "ok" ? PoseFields(row.c0_from_cx) : std::string(",,,,,,")) + tail +
            FormatCsvField(row.status, ',') + "\n";
  }
  return text;
}

Expected<Pose> ReadMarkerFromCamCsv(const std::filesystem::path& path) {
  Expected<CsvTable> table = ReadTable(path);
  if (!table) return table.error();
  if (Status s = table->Require({"tx_mm", "ty_mm", "tz_mm", "qw", "qx", "qy", "qz"}); !s)
    return s.error();
  if (table->doc.rows.size() < 2 || table->doc.rows[1].IsBlank())
    return MakeError(path.string(), 2, 0, "expected one pose row after the header");
  return table->PoseAt(table->doc.rows[1]);
}

Expected<FramePoses> ReadFrameTum(const std::filesystem::path& path) {
  Expected<std::string> text = ReadText(path);
  if (!text) return text.error();
  std::istringstream in(*text);
  FramePoses poses;
  int line_number = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_number;
    if (line.empty() || line[0] == '#' || line.find_first_not_of(" \t\r") == std::string::npos)
      continue;
    std::istringstream fields(line);
    double v[8];
    int count = 0;
    while (count < 8 && fields >> v[count]) ++count;
    std::string rest;
    if (count != 8 || (fields >> rest))
      return MakeError(path.string(), line_number, 0,
                       "expected 8 numbers: frame tx ty tz qx qy qz qw");
    const std::int64_t frame = static_cast<std::int64_t>(v[0]);
    if (static_cast<double>(frame) != v[0])
      return MakeError(path.string(), line_number, 1, "the first column must be a frame number");
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1.0) > 1e-3)
      return MakeError(path.string(), line_number, 0, "the quaternion must have unit norm");
    Pose pose = Pose::Identity();
    pose.linear() = q.normalized().toRotationMatrix();
    pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!poses.emplace(frame, pose).second)
      return MakeError(path.string(), line_number, 1, "frame " + std::to_string(frame) + " twice");
  }
  return poses;
}

Expected<HandEyeOffsets> ReadHandEyeYaml(const std::filesystem::path& path) {
  Expected<std::string> text = ReadText(path);
  if (!text) return text.error();
  Expected<YamlNode> root = YamlNode::Parse(*text, path.string());
  if (!root) return root.error();
  YamlErrors errors;
  YamlMap map(*root, &errors);
  HandEyeOffsets offsets;
  if (std::optional<std::vector<YamlNode>> cameras = map.List("cameras", Presence::kRequired)) {
    for (const YamlNode& node : *cameras) {
      YamlMap camera(node, &errors);
      std::string serial;
      camera.Read("serial", &serial, Presence::kRequired);
      Pose pose = Pose::Identity();
      if (std::optional<YamlMap> m = camera.Map("marker_from_cam", Presence::kRequired)) {
        ReadPoseMap(*m, &pose);
        m->Finish();
      }
      camera.Finish();
      if (errors.ok() && !offsets.emplace(serial, pose).second)
        camera.Fail(node, "camera " + serial + " given twice");
    }
  }
  map.Finish();
  if (!errors.ok()) return errors.status().error();
  return offsets;
}

std::string FormatHandEyeYaml(const HandEyeOffsets& offsets, const std::string& comment) {
  std::string text = "# " + comment + "\n# marker_from_cam maps camera coordinates into the Vicon "
                     "object (marker cluster) frame; mm\ncameras:\n";
  for (const auto& [serial, pose] : offsets) {
    const Eigen::Quaterniond q(pose.linear());
    const Eigen::Vector3d t = pose.translation();
    char line[400];
    std::snprintf(line, sizeof(line),
                  "  - serial: \"%s\"\n    marker_from_cam: {tx_mm: %.6f, ty_mm: %.6f, tz_mm: "
                  "%.6f, qw: %.12f, qx: %.12f, qy: %.12f, qz: %.12f}\n",
                  serial.c_str(), t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z());
    text += line;
  }
  return text;
}

Expected<SynthGroundTruthInfo> ReadCamerasYaml(const std::filesystem::path& path) {
  Expected<std::string> text = ReadText(path);
  if (!text) return text.error();
  Expected<YamlNode> root = YamlNode::Parse(*text, path.string());
  if (!root) return root.error();
  YamlErrors errors;
  YamlMap map(*root, &errors);  // only the keys evaluation needs; the rest is not checked
  SynthGroundTruthInfo info;
  if (std::optional<YamlMap> vicon = map.Map("vicon", Presence::kOptional)) {
    std::string s;
    int i = 0;
    std::int64_t l = 0;
    double d = 0;
    if (vicon->Child("handedness", Presence::kOptional)) {
      vicon->Read("handedness", &s, Presence::kRequired);
      info.handedness = s;
    }
    if (vicon->Child("rotation", Presence::kOptional)) {
      vicon->Read("rotation", &s, Presence::kRequired);
      info.rotation = s;
    }
    if (vicon->Child("trigger_divider", Presence::kOptional)) {
      vicon->Read("trigger_divider", &i, Presence::kRequired);
      info.trigger_divider = i;
    }
    if (vicon->Child("first_trigger_frame", Presence::kOptional)) {
      vicon->Read("first_trigger_frame", &l, Presence::kRequired);
      info.first_trigger_frame = l;
    }
    if (vicon->Child("rate_hz", Presence::kOptional)) {
      vicon->Read("rate_hz", &d, Presence::kRequired);
      info.rate_hz = d;
    }
    if (vicon->Child("plate_subject", Presence::kOptional)) {
      vicon->Read("plate_subject", &s, Presence::kRequired);
      info.plate_subject = s;
    }
  }
  if (std::optional<YamlMap> plate = map.Map("plate", Presence::kOptional)) {
    PlateTemplate t = DefaultPlateTemplate();
    bool complete = true;
    if (std::optional<YamlMap> centers = plate->Map("aruco_centers_mm", Presence::kRequired)) {
      for (int id = 0; id < 4; ++id) {
        std::optional<YamlNode> c = centers->Child(std::to_string(id), Presence::kRequired);
        std::optional<Eigen::Vector3d> p;
        if (c) p = ReadPoint(*centers, *c);
        if (p)
          t.aruco_centers_mm[id] = *p;
        else
          complete = false;
      }
    }
    if (std::optional<std::vector<YamlNode>> markers =
            plate->List("vicon_markers_mm", Presence::kRequired)) {
      if (markers->size() != 4) {
        plate->Fail(plate->node(), "vicon_markers_mm: expected 4 markers");
        complete = false;
      }
      for (std::size_t k = 0; k < markers->size() && k < 4; ++k) {
        std::optional<Eigen::Vector3d> p = ReadPoint(*plate, (*markers)[k]);
        if (p)
          t.vicon_markers_mm[k] = *p;
        else
          complete = false;
      }
    }
    if (complete) info.plate = t;
  }
  if (std::optional<std::vector<YamlNode>> cameras = map.List("cameras", Presence::kOptional)) {
    for (const YamlNode& node : *cameras) {
      YamlMap camera(node, &errors);
      std::string serial, subject;
      camera.Read("serial", &serial, Presence::kRequired);
      camera.Read("vicon_subject", &subject, Presence::kRequired);
      info.serials.push_back(serial);
      info.vicon_subject[serial] = subject;
    }
  }
  if (!errors.ok()) return errors.status().error();
  return info;
}

}  // namespace lifmcr
