// Text rendering of the `lifmcr info` report: the same facts as --json.

#include "apps/info_gentl.h"
#include "apps/info_report.h"

#include "config/text_escape.h"

#include <cstdio>
#include <sstream>
#include <string>

namespace lifmcr::apps {
namespace {

using nlohmann::json;

std::string Num(double value, int decimals = 3) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

std::string Pair(const json& v, int decimals = 3) {
  return "(" + Num(v[0].get<double>(), decimals) + ", " + Num(v[1].get<double>(), decimals) + ")";
}

std::string Pad(int depth) { return std::string(2 * depth, ' '); }

void Problems(std::ostream& out, const json& section, int depth) {
  if (!section.contains("problems")) return;
  for (const auto& p : section["problems"])
    out << Pad(depth) << "PROBLEM: " << p.get<std::string>() << "\n";
}

void Mla(std::ostream& out, const json& m, int depth) {
  out << Pad(depth) << "MLA " << m["file"].get<std::string>() << "\n";
  if (!m.contains("diameter_px")) return Problems(out, m, depth + 1);
  out << Pad(depth + 1) << "pitch " << Num(m["diameter_px"], 3) << " px, rotation "
      << Num(m["rotation_rad"], 6) << " rad (" << Num(m["rotation_deg"], 3) << " deg), offset "
      << Pair(m["offset_px_y_up"]) << " px (y up), border " << Num(m["lens_border_px"], 1)
      << " px, tcp " << Num(m["tcp_virtual_depth"], 3) << "\n";
  out << Pad(depth + 1) << "bases: lens_base_x " << Pair(m["lens_base_x"]) << ", lens_base_y "
      << Pair(m["lens_base_y"]) << ", sub_grid_base " << Pair(m["sub_grid_base"]) << "\n";
  const json& d = m["distortion"];
  out << Pad(depth + 1) << "distortion: " << d["function"].get<std::string>();
  if (!d["parameters"].empty()) {
    out << " [";
    for (std::size_t i = 0; i < d["parameters"].size(); ++i)
      out << (i ? "; " : "") << d["parameters"][i].get<double>();
    out << "] centre " << Pair(d["offset_px"]) << " px";
  }
  out << "\n";
  for (const auto& t : m["lens_types"]) {
    out << Pad(depth + 1) << "lens type id " << t["id"].get<int>() << " (paper type "
        << t["paper_type"].get<int>() << "): offset " << Pair(t["offset_lens"], 1)
        << " lens, virtual depth " << Num(t["depth_min"], 2) << " .. " << Num(t["depth_max"], 2)
        << "\n";
  }
  if (m.contains("reference_lens_px"))
    out << Pad(depth + 1) << "reference lens at " << Pair(m["reference_lens_px"], 2) << " px\n";
  Problems(out, m, depth + 1);
}

void Bmp(std::ostream& out, const json& b, int depth) {
  out << Pad(depth) << "raw image " << b["file"].get<std::string>();
  if (b.contains("width")) {
    out << ": " << b["width"].get<int>() << "x" << b["height"].get<int>() << " "
        << b["pixel_format"].get<std::string>() << ", " << b["row_order"].get<std::string>() << ", "
        << b["file_size"].get<std::size_t>() << " bytes";
    if (b.contains("palette")) out << ", palette " << b["palette"].get<std::string>();
  }
  out << "\n";
  Problems(out, b, depth + 1);
}

void Vicon(std::ostream& out, const json& v, int depth) {
  out << Pad(depth) << "Vicon " << v["file"].get<std::string>();
  if (v.contains("delimiter"))
    out << " ('" << v["delimiter"].get<std::string>() << "' delimited, "
        << v["line_endings"].get<std::string>() << ")";
  out << "\n";
  if (v.contains("blocks")) {
    for (const auto& b : v["blocks"]) {
      out << Pad(depth + 1) << "block " << b["name"].get<std::string>() << ": "
          << b["rate_hz"].get<int>() << " Hz, " << b["frames"].get<std::size_t>() << " frames";
      if (b["frames"].get<std::size_t>() > 0)
        out << " (" << b["first_frame"].get<long long>() << ".." << b["last_frame"].get<long long>()
            << ")";
      out << ", " << b["entities"].get<std::size_t>()
          << " entities (markers, segments or objects), units";
      for (const auto& u : b["units"]) out << " " << u.get<std::string>();
      out << "\n";
      for (const auto& s : b["subjects"]) {
        out << Pad(depth + 2) << s["name"].get<std::string>() << ": "
            << s["frames_with_missing_data"].get<std::size_t>() << " frames with missing data\n";
      }
    }
  }
  Problems(out, v, depth + 1);
}

void Vsk(std::ostream& out, const json& v, int depth) {
  out << Pad(depth) << "VSK " << v["file"].get<std::string>();
  if (v.contains("version")) {
    out << " (version " << v["version"].get<std::string>();
    if (v.contains("model")) out << ", model " << v["model"].get<std::string>();
    out << "): " << v["segments"].get<std::size_t>() << " segments, "
        << v["markers"].get<std::size_t>() << " markers";
  }
  out << "\n";
  if (v.contains("subjects")) {
    for (const auto& s : v["subjects"]) {
      out << Pad(depth + 1) << "object " << s["name"].get<std::string>() << ":";
      if (s.contains("markers")) {
        out << " " << s["markers"].size() << " markers\n";
        for (const auto& m : s["markers"]) {
          const auto& p = m["position_mm"];
          out << Pad(depth + 2) << m["name"].get<std::string>() << " (" << Num(p[0], 2) << ", "
              << Num(p[1], 2) << ", " << Num(p[2], 2) << ") mm in "
              << m["segment"].get<std::string>() << "\n";
        }
      } else {
        out << " no markers\n";
      }
    }
  }
  Problems(out, v, depth + 1);
}

void Camera(std::ostream& out, const json& c, int depth) {
  out << Pad(depth) << "camera " << c["serial"].get<std::string>() << ": "
      << c["frame_count"].get<std::size_t>() << " frames";
  if (c.contains("first_frame"))
    out << " (" << c["first_frame"].get<long long>() << ".." << c["last_frame"].get<long long>()
        << ")";
  const long long missing = c["missing_count"].get<long long>();
  out << ", " << missing << " missing";
  if (missing > 0) {
    out << ":";
    for (const auto& m : c["missing"]) out << " " << m.get<long long>();
    if (missing > static_cast<long long>(c["missing"].size())) out << " ...";
  }
  if (c.contains("image")) {
    const json& i = c["image"];
    out << ", " << i["width"].get<int>() << "x" << i["height"].get<int>() << " "
        << i["pixel_format"].get<std::string>() << " " << i["row_order"].get<std::string>();
  }
  out << " (" << c["frames_checked"].get<std::size_t>() << " headers checked)\n";
  if (c.contains("unrecognised_files")) {
    out << Pad(depth + 1) << "files not named as frames:";
    for (const auto& f : c["unrecognised_files"]) out << " " << f.get<std::string>();
    out << "\n";
  }
  if (c["mla"].is_null())
    out << Pad(depth + 1) << "MLA: no TypeE_" << c["serial"].get<std::string>()
        << "_MLA.xml found in a Calibration folder\n";
  else
    Mla(out, c["mla"], depth + 1);
  Problems(out, c, depth + 1);
}

void Unrecognised(std::ostream& out, const json& section, int depth) {
  if (!section.contains("unrecognised")) return;
  out << Pad(depth) << "not part of the layout:";
  for (const auto& u : section["unrecognised"]) out << " " << u.get<std::string>();
  out << "\n";
}

void Sequence(std::ostream& out, const json& s, int depth) {
  out << Pad(depth) << "sequence " << s["scene"].get<std::string>() << "/"
      << s["name"].get<std::string>() << " (" << s["cameras"].size() << " cameras, "
      << s["vicon"].size() << " Vicon files, ground truth "
      << (s["ground_truth"].get<bool>() ? "present" : "absent") << ")\n";
  for (const auto& c : s["cameras"]) Camera(out, c, depth + 1);
  for (const auto& v : s["vicon"]) Vicon(out, v, depth + 1);
  if (s.contains("vsk"))
    for (const auto& v : s["vsk"]) Vsk(out, v, depth + 1);
  Unrecognised(out, s, depth + 1);
  Problems(out, s, depth + 1);
}

void Calibration(std::ostream& out, const json& c, int depth) {
  out << Pad(depth) << "calibration " << c["dir"].get<std::string>() << "\n";
  for (const auto& [serial, mla] : c["mla"].items()) Mla(out, mla, depth + 1);
  for (const auto& [serial, images] : c["white_images"].items()) {
    out << Pad(depth + 1) << "white images of " << serial << ": " << images.size() << "\n";
    for (const auto& b : images) Bmp(out, b, depth + 2);
  }
  for (const auto& v : c["vsk"]) Vsk(out, v, depth + 1);
  Unrecognised(out, c, depth + 1);
}

void Scene(std::ostream& out, const json& s, int depth) {
  out << Pad(depth) << "scene " << s["name"].get<std::string>() << ": " << s["sequences"].size()
      << " sequences\n";
  for (const auto& q : s["sequences"]) Sequence(out, q, depth + 1);
  Unrecognised(out, s, depth + 1);
}

// The report with every string (keys too) escaped for a terminal: a file
// named "x\n  PROBLEM: none" must not forge report lines.
json Escaped(const json& value) {
  if (value.is_string()) return EscapeText(value.get_ref<const std::string&>());
  if (value.is_array()) {
    json out = json::array();
    for (const json& element : value) out.push_back(Escaped(element));
    return out;
  }
  if (value.is_object()) {
    json out = json::object();
    for (const auto& [key, element] : value.items()) out[EscapeText(key)] = Escaped(element);
    return out;
  }
  return value;
}

}  // namespace

std::string FormatInfoText(const json& raw_report) {
  const json report = Escaped(raw_report);
  std::ostringstream out;
  out << report["path"].get<std::string>() << ": " << report["kind"].get<std::string>() << "\n";
  if (report.contains("scenes")) {
    out << "  " << report["scenes"].size() << " scenes\n";
    for (const auto& s : report["scenes"]) Scene(out, s, 1);
  }
  if (report.contains("scene")) Scene(out, report["scene"], 1);
  if (report.contains("sequence")) Sequence(out, report["sequence"], 1);
  if (report.contains("camera")) Camera(out, report["camera"], 1);
  if (report.contains("calibration")) Calibration(out, report["calibration"], 1);
  Unrecognised(out, report, 1);
  if (report.contains("bmp")) Bmp(out, report["bmp"], 1);
  if (report.contains("mla")) Mla(out, report["mla"], 1);
  if (report.contains("vicon")) Vicon(out, report["vicon"], 1);
  if (report.contains("vsk")) Vsk(out, report["vsk"], 1);
  if (report.contains("rig")) {
    const json& r = report["rig"];
    out << "  rig " << r.value("name", std::string()) << "\n";
    if (r.contains("cameras")) {
      for (const auto& c : r["cameras"]) {
        out << "    camera " << c["serial"].get<std::string>() << " ("
            << c["name"].get<std::string>() << ", " << c["role"].get<std::string>() << "): driver "
            << c["driver"].get<std::string>()
            << (c["address"].get<std::string>().empty() ? ""
                                                        : " at " + c["address"].get<std::string>())
            << ", trigger " << c["trigger"].get<std::string>() << ", "
            << c["pixel_format"].get<std::string>() << ", Vicon object '"
            << c["vicon_object"].get<std::string>() << "', MLA " << c["mla_file"].get<std::string>()
            << "\n";
        if (c.contains("mla")) Mla(out, c["mla"], 3);
        if (c.contains("gentl")) out << FormatGenTlText(c["gentl"], "      ");
      }
      const json& v = r["vicon"];
      out << "    Vicon: " << v["source"].get<std::string>() << ", " << v["rate_hz"].get<double>()
          << " Hz, trigger every " << v["trigger_divider"].get<int>() << " frames, rotation "
          << v["rotation"].get<std::string>() << ", handedness "
          << v["handedness"].get<std::string>() << ", plate '"
          << v["plate_object"].get<std::string>() << "'\n";
      if (v.contains("csv")) Vicon(out, v["csv"], 3);
      if (v.contains("vsk")) Vsk(out, v["vsk"], 3);
    }
    Problems(out, r, 2);
  }
  const std::size_t problems = report["problems"].size();
  out << (problems == 0 ? "no problems found\n" : std::to_string(problems) + " problem(s) found\n");
  return out.str();
}

}  // namespace lifmcr::apps
