#include "apps/info_report.h"

#include "apps/info_gentl.h"
#include "config/input_file.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"
#include "replay/vsk.h"

#include <cmath>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Missing frame numbers listed in the report; the count is always complete.
constexpr std::size_t kMaxListedMissing = 50;

json Vec2(const Eigen::Vector2d& v) { return json::array({v.x(), v.y()}); }

class Reporter {
 public:
  explicit Reporter(const InfoOptions& options) : options_(options) {}

  json& problems() { return problems_; }

  void Problem(json& section, const std::string& message) {
    section["problems"].push_back(message);
    problems_.push_back(message);
  }

  json Mla(const fs::path& path) {
    json out{{"file", path.string()}};
    auto mla = ReadMlaXml(path);
    if (!mla.ok()) {
      Problem(out, mla.error().message);
      return out;
    }
    const MlaCalibration& m = *mla;
    out["version"] = m.version;
    out["diameter_px"] = m.diameter_px;
    out["rotation_rad"] = m.rotation_rad;
    out["rotation_deg"] = m.rotation_rad * 180.0 / M_PI;
    out["offset_px_y_up"] = Vec2(m.offset_px);
    out["lens_border_px"] = m.lens_border_px;
    out["tcp_virtual_depth"] = m.tcp_virtual_depth;
    out["lens_base_x"] = Vec2(m.lens_base_x);
    out["lens_base_y"] = Vec2(m.lens_base_y);
    out["sub_grid_base"] = Vec2(m.sub_grid_base);
    out["distortion"] = {{"type", m.distortion.type},
                         {"function", m.distortion.function},
                         {"parameters", m.distortion.parameters},
                         {"offset_px", Vec2(m.distortion.offset_px)}};
    for (const MlaLensType& t : m.lens_types) {
      out["lens_types"].push_back({{"id", t.id},
                                   {"paper_type", t.id + 1},
                                   {"offset_lens", Vec2(t.offset_lens)},
                                   {"depth_min", t.depth_min},
                                   {"depth_max", t.depth_max}});
    }
    mla_cache_[path] = m;
    return out;
  }

  json Bmp(const fs::path& path) {
    json out{{"file", path.string()}};
    auto header = ReadBmpHeader(path);
    if (!header.ok()) {
      Problem(out, header.error().message);
      return out;
    }
    out["width"] = header->width;
    out["height"] = header->height;
    out["pixel_format"] = std::string(ToString(header->format));
    out["row_order"] = header->top_down ? "top-down" : "bottom-up";
    out["file_size"] = header->file_size;
    if (!header->palette_is_grey) out["palette"] = "not grey (colour-mapped 8-bit)";
    return out;
  }

  json ViconCsv(const fs::path& path) {
    json out{{"file", path.string()}};
    auto csv = ReadViconCsv(path);
    if (!csv.ok()) {
      Problem(out, csv.error().message);
      return out;
    }
    out["delimiter"] = std::string(1, csv->delimiter);
    out["line_endings"] = csv->crlf ? "CRLF" : "LF";
    for (const ViconBlockSummary& s : Summarize(*csv)) {
      json block{{"name", s.name},
                 {"rate_hz", s.rate_hz},
                 {"frames", s.num_frames},
                 {"first_frame", s.first_frame},
                 {"last_frame", s.last_frame},
                 {"entities", s.num_entities},
                 {"units", s.units}};
      for (std::size_t i = 0; i < s.subjects.size(); ++i) {
        block["subjects"].push_back(
            {{"name", s.subjects[i]},
             {"frames_with_missing_data",
              i < s.frames_with_missing.size() ? s.frames_with_missing[i] : 0}});
      }
      out["blocks"].push_back(std::move(block));
    }
    return out;
  }

  json Vsk(const fs::path& path) {
    json out{{"file", path.string()}};
    auto vsk = ReadVsk(path);
    if (!vsk.ok()) {
      Problem(out, vsk.error().message);
      return out;
    }
    out["version"] = vsk->version;
    if (!vsk->model.empty()) out["model"] = vsk->model;
    out["segments"] = vsk->segments.size();
    out["markers"] = vsk->markers.size();
    for (const auto& [subject, markers] : VskMarkersBySubject(*vsk)) {
      json s{{"name", subject}};
      for (const VskMarker& marker : markers) {
        const Eigen::Vector3d& p = marker.position_mm;
        s["markers"].push_back({{"name", marker.name},
                                {"segment", marker.segment},
                                {"position_mm", json::array({p.x(), p.y(), p.z()})}});
      }
      out["subjects"].push_back(std::move(s));
    }
    return out;
  }

  json Rig(const fs::path& path) {
    json out{{"file", path.string()}};
    auto rig = LoadRigConfig(path);
    if (!rig.ok()) {
      Problem(out, rig.error().message);
      return out;
    }
    out["name"] = rig->name;
    for (const CameraConfig& c : rig->cameras) {
      out["cameras"].push_back({{"serial", c.serial},
                                {"name", c.name},
                                {"role", std::string(ToString(c.role))},
                                {"driver", std::string(ToString(c.driver.kind))},
                                {"address", c.driver.address},
                                {"trigger", std::string(ToString(c.trigger.mode))},
                                {"pixel_format", std::string(ToString(c.pixel_format))},
                                {"mla_file", c.mla_file.string()},
                                {"vicon_object", c.vicon_object}});
      // The loader checks that the MLA file exists; whether it is an MLA
      // calibration is the MLA reader's to say (a rig naming another file
      // would otherwise pass here and fail only when recording starts).
      out["cameras"].back()["mla"] = Mla(c.mla_file);
      // What the producer exposes; its problems (no producer on this
      // machine) stay in the section: the rig file itself is fine.
      if (c.driver.kind == DriverKind::kGenTl)
        out["cameras"].back()["gentl"] = DescribeGenTlCamera(c);
    }
    const ViconConfig& v = rig->vicon;
    out["vicon"] = {{"source", std::string(ToString(v.source))},
                    {"rotation", std::string(ToString(v.rotation))},
                    {"handedness", std::string(ToString(v.handedness))},
                    {"rate_hz", v.rate_hz},
                    {"trigger_divider", v.trigger_divider},
                    {"plate_object", v.plate_object}};
    // The other files the rig names, read as their commands read them.
    if (!v.csv.empty()) out["vicon"]["csv"] = ViconCsv(v.csv);
    if (!v.vsk.empty()) out["vicon"]["vsk"] = Vsk(v.vsk);
    return out;
  }

  json Camera(const CameraFolder& camera, const std::optional<fs::path>& mla_path) {
    json out{{"serial", camera.serial},
             {"dir", camera.dir.string()},
             {"frame_count", camera.frames.size()},
             {"missing_count", camera.missing_count}};
    if (!camera.frames.empty()) {
      out["first_frame"] = camera.frames.front();
      out["last_frame"] = camera.frames.back();
    }
    for (std::size_t i = 0; i < camera.missing.size() && i < kMaxListedMissing; ++i)
      out["missing"].push_back(camera.missing[i]);
    if (!camera.unrecognised_files.empty()) out["unrecognised_files"] = camera.unrecognised_files;
    CheckFrames(camera, out);
    if (mla_path) {
      out["mla"] = Mla(*mla_path);
      CheckMlaAgainstImage(*mla_path, out);
    } else {
      out["mla"] = nullptr;
    }
    return out;
  }

  json Sequence(const SequenceLayout& sequence) {
    json out{{"name", sequence.name},
             {"scene", sequence.scene},
             {"dir", sequence.dir.string()},
             {"ground_truth", sequence.has_ground_truth}};
    std::optional<CalibrationLayout> calibration;
    if (auto dir = FindCalibrationFor(sequence.dir)) {
      auto found = DiscoverCalibration(*dir);
      if (found.ok())
        calibration = std::move(found).value();
      else
        Problem(out, found.error().message);  // its cameras' MLA files cannot be found
      out["calibration_dir"] = dir->string();
    }
    out["cameras"] = json::array();
    for (const CameraFolder& camera : sequence.cameras) {
      std::optional<fs::path> mla;
      if (calibration) {
        auto it = calibration->mla_xml.find(camera.serial);
        if (it != calibration->mla_xml.end()) mla = it->second;
      }
      out["cameras"].push_back(Camera(camera, mla));
    }
    out["vicon"] = json::array();
    for (const fs::path& csv : sequence.vicon_csvs) out["vicon"].push_back(ViconCsv(csv));
    if (calibration) {
      for (const fs::path& vsk : calibration->vsk) out["vsk"].push_back(Vsk(vsk));
    }
    for (const fs::path& p : sequence.unrecognised) out["unrecognised"].push_back(p.string());
    return out;
  }

  json Calibration(const CalibrationLayout& calibration) {
    json out{{"dir", calibration.dir.string()}};
    out["mla"] = json::object();
    for (const auto& [serial, path] : calibration.mla_xml) out["mla"][serial] = Mla(path);
    out["white_images"] = json::object();
    for (const auto& [serial, paths] : calibration.white_images) {
      json images = json::array();
      for (const fs::path& p : paths) images.push_back(Bmp(p));
      out["white_images"][serial] = std::move(images);
    }
    out["vsk"] = json::array();
    for (const fs::path& vsk : calibration.vsk) out["vsk"].push_back(Vsk(vsk));
    for (const fs::path& p : calibration.unrecognised) out["unrecognised"].push_back(p.string());
    return out;
  }

  json Scene(const SceneLayout& scene) {
    json out{{"name", scene.name}, {"dir", scene.dir.string()}, {"sequences", json::array()}};
    for (const SequenceLayout& sequence : scene.sequences)
      out["sequences"].push_back(Sequence(sequence));
    for (const fs::path& p : scene.unrecognised) out["unrecognised"].push_back(p.string());
    return out;
  }

 private:
  // Every frame's header must agree with its file and with the first frame.
  void CheckFrames(const CameraFolder& camera, json& out) {
    std::optional<BmpHeader> first;
    std::size_t checked = 0;
    for (std::size_t i = 0; i < camera.frames.size(); ++i) {
      const bool ends = i == 0 || i + 1 == camera.frames.size();
      if (!options_.check_every_frame && !ends) continue;
      const fs::path path = camera.dir / camera.frame_files[i];
      auto header = ReadBmpHeader(path);
      ++checked;
      if (options_.progress && (checked % 256 == 0 || i + 1 == camera.frames.size()))
        options_.progress(camera.serial, checked,
                          options_.check_every_frame ? camera.frames.size() : 2);
      if (!header.ok()) {
        Problem(out, header.error().message);
        continue;
      }
      if (!first) {
        first = *header;
        out["image"] = {{"width", header->width},
                        {"height", header->height},
                        {"pixel_format", std::string(ToString(header->format))},
                        {"row_order", header->top_down ? "top-down" : "bottom-up"}};
      } else if (header->width != first->width || header->height != first->height ||
                 header->format != first->format) {
        Problem(out, path.string() + ": frame is " + std::to_string(header->width) + "x" +
                         std::to_string(header->height) + " " +
                         std::string(ToString(header->format)) + ", the camera's first frame is " +
                         std::to_string(first->width) + "x" + std::to_string(first->height) + " " +
                         std::string(ToString(first->format)));
      }
    }
    out["frames_checked"] = checked;
  }

  // The MLA file has no image size; its reference lens must at least fall
  // inside the frames it is paired with.
  void CheckMlaAgainstImage(const fs::path& mla_path, json& out) {
    auto it = mla_cache_.find(mla_path);
    if (it == mla_cache_.end() || !out.contains("image")) return;
    const int w = out["image"]["width"], h = out["image"]["height"];
    const Eigen::Vector2d c = it->second.ReferenceLensCenterPx(w, h);
    out["mla"]["reference_lens_px"] = Vec2(c);
    if (c.x() < 0 || c.y() < 0 || c.x() > w - 1 || c.y() > h - 1) {
      Problem(out, mla_path.string() + ": the reference lens centre (" + std::to_string(c.x()) +
                       ", " + std::to_string(c.y()) + ") px lies outside the camera's " +
                       std::to_string(w) + "x" + std::to_string(h) + " frames");
    }
  }

  InfoOptions options_;
  json problems_ = json::array();
  std::map<fs::path, MlaCalibration> mla_cache_;
};

// Every string (keys too) as valid UTF-8, so dumping never throws; control
// characters are left for JSON's own escapes.
json ValidUtf8(const json& value) {
  if (value.is_string()) return ToValidUtf8(value.get_ref<const std::string&>());
  if (value.is_array()) {
    json out = json::array();
    for (const json& element : value) out.push_back(ValidUtf8(element));
    return out;
  }
  if (value.is_object()) {
    json out = json::object();
    for (const auto& [key, element] : value.items()) out[ToValidUtf8(key)] = ValidUtf8(element);
    return out;
  }
  return value;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

Expected<json> DescribePath(const fs::path& path, const InfoOptions& options) {
  std::error_code ec;
  if (const std::string missing = DescribeMissingPath(path); !missing.empty())
    return Error{EscapeText(path.string()) + ": " + missing};
  Reporter reporter(options);
  json report{{"path", path.string()}};
  const PathKind kind = ClassifyPath(path);
  report["kind"] = std::string(ToString(kind));

  switch (kind) {
    case PathKind::kDatasetRoot: {
      auto dataset = DiscoverDataset(path);
      if (!dataset.ok()) return dataset.error();
      report["scenes"] = json::array();
      for (const SceneLayout& scene : dataset->scenes)
        report["scenes"].push_back(reporter.Scene(scene));
      if (dataset->calibration) report["calibration"] = reporter.Calibration(*dataset->calibration);
      for (const fs::path& p : dataset->unrecognised) report["unrecognised"].push_back(p.string());
      break;
    }
    case PathKind::kScene: {
      auto scene = DiscoverScene(path);
      if (!scene.ok()) return scene.error();
      report["scene"] = reporter.Scene(*scene);
      break;
    }
    case PathKind::kSequence: {
      auto sequence = DiscoverSequence(path);
      if (!sequence.ok()) return sequence.error();
      report["sequence"] = reporter.Sequence(*sequence);
      break;
    }
    case PathKind::kCameraFolder: {
      auto camera = DiscoverCameraFolder(path);
      if (!camera.ok()) return camera.error();
      std::optional<fs::path> mla;
      if (auto calibration_dir = FindCalibrationFor(path.parent_path())) {
        const fs::path candidate = layout::MlaXmlPath(*calibration_dir, camera->serial);
        if (fs::exists(candidate, ec)) mla = candidate;
      }
      report["camera"] = reporter.Camera(*camera, mla);
      break;
    }
    case PathKind::kCalibration: {
      auto calibration = DiscoverCalibration(path);
      if (!calibration.ok()) return calibration.error();
      report["calibration"] = reporter.Calibration(*calibration);
      break;
    }
    case PathKind::kFile: {
      const std::string ext = Lower(path.extension().string());
      if (ext == ".bmp") {
        report["kind"] = "raw image";
        report["bmp"] = reporter.Bmp(path);
      } else if (ext == ".xml") {
        report["kind"] = "MLA calibration";
        report["mla"] = reporter.Mla(path);
      } else if (ext == ".csv") {
        report["kind"] = "Vicon CSV";
        report["vicon"] = reporter.ViconCsv(path);
      } else if (ext == ".vsk") {
        report["kind"] = "Vicon VSK";
        report["vsk"] = reporter.Vsk(path);
      } else if (ext == ".yaml" || ext == ".yml") {
        report["kind"] = "rig file";
        report["rig"] = reporter.Rig(path);
      } else {
        const std::string type = DescribeNonRegular(path);
        return Error{EscapeText(path.string()) + (type.empty() ? "" : ": " + type) +
                     ": not a file lifmcr knows (expected .bmp raw frame, .xml MLA calibration, "
                     ".csv Vicon export, .vsk Vicon model or .yaml rig file)"};
      }
      break;
    }
    case PathKind::kUnknown:
      return Error{EscapeText(path.string()) +
                   ": not a LiFMCR dataset root, scene, sequence, camera folder or calibration "
                   "folder (see `lifmcr info --help` for what each holds)"};
  }
  report["problems"] = reporter.problems();
  return ValidUtf8(report);
}

}  // namespace lifmcr::apps
