#include "replay/mla_xml.h"

#include "config/text_escape.h"
#include "replay/xml_util.h"

#include <tinyxml2.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

namespace lifmcr {
namespace {

using tinyxml2::XMLElement;

constexpr char kRoot[] = "/RayCalibData";
// Tolerance on the hex basis: float32 noise in real files is ~1e-7.
constexpr double kBasisTolerance = 1e-3;

// ---------------------------------------------------------------- checks

struct MlaProblem {
  std::string path;  // element path, as xml::ElementPath writes it
  std::string what;
};

std::string LensTypePath(int id) {
  return std::string(kRoot) + "/lens_type[@id='" + std::to_string(id) + "']";
}

std::string Number(double value) { return xml::FormatShortest(value); }

std::optional<MlaProblem> FindProblem(const MlaCalibration& c) {
  const std::string root = kRoot;
  // Finite values first: everything after compares numbers.
  std::vector<std::pair<std::string, double>> values = {
      {root + "/offset", c.offset_px.x()},
      {root + "/offset", c.offset_px.y()},
      {root + "/diameter", c.diameter_px},
      {root + "/rotation", c.rotation_rad},
      {root + "/lens_border", c.lens_border_px},
      {root + "/tcp", c.tcp_virtual_depth},
      {root + "/lens_base_x", c.lens_base_x.x()},
      {root + "/lens_base_x", c.lens_base_x.y()},
      {root + "/lens_base_y", c.lens_base_y.x()},
      {root + "/lens_base_y", c.lens_base_y.y()},
      {root + "/sub_grid_base", c.sub_grid_base.x()},
      {root + "/sub_grid_base", c.sub_grid_base.y()},
      {root + "/distortion/offset", c.distortion.offset_px.x()},
      {root + "/distortion/offset", c.distortion.offset_px.y()},
  };
  for (double p : c.distortion.parameters) values.push_back({root + "/distortion/parameter", p});
  for (int id = 0; id < 3; ++id) {
    const MlaLensType& type = c.lens_types[id];
    values.push_back({LensTypePath(id) + "/offset", type.offset_lens.x()});
    values.push_back({LensTypePath(id) + "/offset", type.offset_lens.y()});
    values.push_back({LensTypePath(id) + "/depth_range", type.depth_min});
    values.push_back({LensTypePath(id) + "/depth_range", type.depth_max});
  }
  for (const auto& [path, value] : values) {
    if (!std::isfinite(value))
      return MlaProblem{path, "expected a finite number, got " + Number(value)};
  }

  if (c.version != "1.0") {
    return MlaProblem{root, "expected version \"1.0\", got \"" + Excerpt(c.version) + "\""};
  }
  // What a real camera and lens can be (README, "Limits of every input"):
  // garbage that passes here would crash or exhaust memory in processing.
  const struct {
    std::string path;
    double value, min, max;
    const char* unit;
  } ranges[] = {
      {root + "/offset", std::abs(c.offset_px.x()), 0, kMlaLimits.max_offset_px, "px (|x|)"},
      {root + "/offset", std::abs(c.offset_px.y()), 0, kMlaLimits.max_offset_px, "px (|y|)"},
      {root + "/diameter", c.diameter_px, kMlaLimits.min_diameter_px, kMlaLimits.max_diameter_px,
       "px"},
      {root + "/rotation", std::abs(c.rotation_rad), 0, kMlaLimits.max_abs_rotation_rad,
       "rad (|rotation|)"},
      {root + "/tcp", c.tcp_virtual_depth, kMlaLimits.min_virtual_depth,
       kMlaLimits.max_virtual_depth, "(virtual depth)"},
      {root + "/sub_grid_base", c.sub_grid_base.norm(), 0, kMlaLimits.max_basis_lens,
       "lens diameters (length)"},
      {root + "/distortion/offset", std::abs(c.distortion.offset_px.x()), 0,
       kMlaLimits.max_offset_px, "px (|x|)"},
      {root + "/distortion/offset", std::abs(c.distortion.offset_px.y()), 0,
       kMlaLimits.max_offset_px, "px (|y|)"},
  };
  for (const auto& r : ranges) {
    if (r.value < r.min || r.value > r.max) {
      return MlaProblem{r.path, "expected " + Number(r.min) + " .. " + Number(r.max) + " " +
                                    r.unit + ", got " + Number(r.value) +
                                    " (outside what a real camera can have)"};
    }
  }
  for (double p : c.distortion.parameters) {
    if (std::abs(p) > kMlaLimits.max_abs_distortion_parameter) {
      return MlaProblem{root + "/distortion/parameter",
                        "expected parameters of magnitude <= " +
                            Number(kMlaLimits.max_abs_distortion_parameter) + ", got " + Number(p)};
    }
  }
  if (c.distortion.parameters.size() > kMlaLimits.max_distortion_parameters) {
    return MlaProblem{root + "/distortion/parameter",
                      "expected at most " + std::to_string(kMlaLimits.max_distortion_parameters) +
                          " parameters, got " + std::to_string(c.distortion.parameters.size())};
  }
  for (int id = 0; id < 3; ++id) {
    const MlaLensType& type = c.lens_types[id];
    if (type.offset_lens.cwiseAbs().maxCoeff() > kMlaLimits.max_basis_lens) {
      return MlaProblem{LensTypePath(id) + "/offset",
                        "expected |x|, |y| <= " + Number(kMlaLimits.max_basis_lens) +
                            " lens diameters, got (" + Number(type.offset_lens.x()) + ", " +
                            Number(type.offset_lens.y()) + ")"};
    }
    for (double v : {type.depth_min, type.depth_max}) {
      if (v < 0.0 || v > kMlaLimits.max_virtual_depth) {
        return MlaProblem{LensTypePath(id) + "/depth_range",
                          "expected virtual depths 0 .. " + Number(kMlaLimits.max_virtual_depth) +
                              ", got " + Number(v)};
      }
    }
  }
  if (!(c.diameter_px > 0.0)) {
    return MlaProblem{root + "/diameter",
                      "expected a diameter > 0 px, got " + Number(c.diameter_px)};
  }
  if (c.lens_border_px < 0.0 || c.lens_border_px >= c.diameter_px / 2.0) {
    return MlaProblem{root + "/lens_border",
                      "expected 0 <= lens_border < diameter/2 = " + Number(c.diameter_px / 2.0) +
                          " px, got " + Number(c.lens_border_px)};
  }
  const double norm_x = c.lens_base_x.norm();
  const double norm_y = c.lens_base_y.norm();
  if (std::abs(norm_x - 1.0) > kBasisTolerance) {
    return MlaProblem{
        root + "/lens_base_x",
        "expected a unit vector (hexagonal grid, lens diameters), got length " + Number(norm_x)};
  }
  if (std::abs(norm_y - 1.0) > kBasisTolerance) {
    return MlaProblem{
        root + "/lens_base_y",
        "expected a unit vector (hexagonal grid, lens diameters), got length " + Number(norm_y)};
  }
  // Hexagonal grid: the two bases are 60 or 120 degrees apart, |cos| = 1/2.
  const double cos_angle = c.lens_base_x.dot(c.lens_base_y) / (norm_x * norm_y);
  if (std::abs(std::abs(cos_angle) - 0.5) > kBasisTolerance) {
    const double angle_deg = std::acos(std::clamp(cos_angle, -1.0, 1.0)) * 180.0 / std::numbers::pi;
    return MlaProblem{root + "/lens_base_y",
                      "expected lens_base_x and lens_base_y 60 or 120 degrees apart (hexagonal "
                      "grid), got " +
                          Number(angle_deg) + " degrees; the grid is not hexagonal"};
  }
  if (c.distortion.function != "constant" && c.distortion.function != "Brown") {
    return MlaProblem{root + "/distortion/function",
                      "expected 'constant' or 'Brown', got '" + Excerpt(c.distortion.function) +
                          "'"};
  }
  if (c.distortion.type.empty()) {
    return MlaProblem{root + "/distortion", "expected a non-empty type attribute"};
  }
  for (int id = 0; id < 3; ++id) {
    const MlaLensType& type = c.lens_types[id];
    if (type.id != id) {
      return MlaProblem{LensTypePath(id), "lens type at index " + std::to_string(id) + " has id " +
                                              std::to_string(type.id) + ", expected index = id"};
    }
    // The range is where the lens type is sharp, the virtual depths the
    // depth estimation searches (processing/virtual_depth.cpp): an empty one
    // would end in no depth at all, far from this file.
    if (!(type.depth_min < type.depth_max)) {
      return MlaProblem{LensTypePath(id) + "/depth_range",
                        "expected min < max (the virtual depths the lens type is sharp in), got min " +
                            Number(type.depth_min) + (type.depth_min == type.depth_max ? " = max " : " > max ") +
                            Number(type.depth_max)};
    }
  }
  return std::nullopt;
}

// ---------------------------------------------------------------- reading

class Reader {
 public:
  explicit Reader(std::string label) : label_(std::move(label)) {}

  Expected<MlaCalibration> Read(std::string_view text) {
    tinyxml2::XMLDocument doc;
    LIFMCR_XML_RETURN_IF_ERROR(xml::ParseDocument(text, label_, &doc));
    const XMLElement* root = doc.RootElement();
    const std::string expected_root =
        "expected root <RayCalibData version=\"1.0\">; if this is a newer RxLive export, "
        "convert it to RayCalibData 1.0 (the previous standard)";
    if (std::string_view(root->Name()) != "RayCalibData") {
      return xml::ErrorAt(label_, root,
                          "root element is <" + Excerpt(root->Name()) + ">, " + expected_root);
    }
    const char* version = root->Attribute("version");
    if (version == nullptr || std::string_view(version) != "1.0") {
      return xml::ErrorAt(label_, root,
                          std::string("RayCalibData version is ") +
                              (version ? "\"" + Excerpt(version) + "\"" : "missing") + ", " +
                              expected_root);
    }
    Remember(root);

    MlaCalibration c;
    c.version = version;
    LIFMCR_XML_ASSIGN_OR_RETURN(c.offset_px, Vector(root, "offset", "pix"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.diameter_px, Scalar(root, "diameter", "pix"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.rotation_rad, Scalar(root, "rotation", "rad"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.lens_border_px, Scalar(root, "lens_border", "pix"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.tcp_virtual_depth, Scalar(root, "tcp", "virtual_depth"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.lens_base_x, Vector(root, "lens_base_x", "lens"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.lens_base_y, Vector(root, "lens_base_y", "lens"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.sub_grid_base, Vector(root, "sub_grid_base", "lens"));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.distortion, Distortion(root));
    LIFMCR_XML_ASSIGN_OR_RETURN(c.lens_types, LensTypes(root));

    if (const std::optional<MlaProblem> problem = FindProblem(c)) {
      const auto at = elements_.find(problem->path);
      if (at != elements_.end()) return xml::ErrorAt(label_, at->second, problem->what);
      // Only when an attribute was spelled unusually (id="01"): keep the path.
      return MakeError(label_, root->GetLineNum(), 0, problem->path + ": " + problem->what);
    }
    return c;
  }

 private:
  void Remember(const XMLElement* element) { elements_[xml::ElementPath(element)] = element; }

  Status CheckUnits(const XMLElement* element, const char* expected) {
    const char* units = element->Attribute("units");
    if (units == nullptr) {
      return xml::ErrorAt(label_, element,
                          "element " + xml::ElementPath(element) +
                              " has no units attribute, expected units=\"" + expected + "\"");
    }
    if (std::string_view(units) != expected) {
      return xml::ErrorAt(label_, element,
                          "element " + xml::ElementPath(element) + " has units '" + units +
                              "', expected '" + expected + "'");
    }
    return Status::Ok();
  }

  Expected<double> Scalar(const XMLElement* parent, const char* name, const char* units) {
    const XMLElement* element = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(element, xml::UniqueChild(label_, parent, name));
    Remember(element);
    LIFMCR_XML_RETURN_IF_ERROR(CheckUnits(element, units));
    return xml::ElementNumber(label_, element);
  }

  Expected<double> Number(const XMLElement* parent, const char* name) {
    const XMLElement* element = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(element, xml::UniqueChild(label_, parent, name));
    return xml::ElementNumber(label_, element);
  }

  Expected<Eigen::Vector2d> Vector(const XMLElement* parent, const char* name, const char* units) {
    const XMLElement* element = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(element, xml::UniqueChild(label_, parent, name));
    Remember(element);
    LIFMCR_XML_RETURN_IF_ERROR(CheckUnits(element, units));
    Eigen::Vector2d v;
    LIFMCR_XML_ASSIGN_OR_RETURN(v.x(), Number(element, "x"));
    LIFMCR_XML_ASSIGN_OR_RETURN(v.y(), Number(element, "y"));
    return v;
  }

  Expected<std::vector<double>> Parameters(const XMLElement* element) {
    LIFMCR_XML_ASSIGN_OR_RETURN(const std::string count_text,
                                xml::RequiredAttribute(label_, element, "count"));
    int count = 0;
    if (!xml::ParseStrictInt(count_text, &count) || count < 0) {
      return xml::ErrorAt(
          label_, element,
          "expected count=\"N\" with an integer N >= 0, got \"" + Excerpt(count_text) + "\"");
    }
    if (count > static_cast<int>(kMlaLimits.max_distortion_parameters)) {
      return xml::ErrorAt(label_, element,
                          "count=\"" + std::to_string(count) + "\": expected at most " +
                              std::to_string(kMlaLimits.max_distortion_parameters) +
                              " distortion parameters");
    }
    const std::string text = element->GetText() != nullptr ? element->GetText() : "";
    std::vector<double> values;
    if (count == 0) {
      // RxLive writes "0" as the text of an empty list.
      double zero = 0.0;
      const bool empty = text.find_first_not_of(" \t\r\n") == std::string::npos;
      if (!empty && !(xml::ParseStrictDouble(text, &zero) && zero == 0.0)) {
        return xml::ErrorAt(
            label_, element,
            "count=\"0\" but the text is '" + Excerpt(text) + "', expected '0' (no parameters)");
      }
      return values;
    }
    size_t start = 0;
    while (true) {
      const size_t end = text.find(';', start);
      const std::string item = text.substr(start, end == std::string::npos ? end : end - start);
      double value = 0.0;
      if (!xml::ParseStrictDouble(item, &value)) {
        return xml::ErrorAt(label_, element,
                            "value " + std::to_string(values.size() + 1) + " is not a number: '" +
                                Excerpt(item) + "' (expected numbers separated by ';')");
      }
      values.push_back(value);
      if (values.size() > static_cast<std::size_t>(count)) break;  // reported below
      if (end == std::string::npos) break;
      start = end + 1;
    }
    if (static_cast<int>(values.size()) != count) {
      return xml::ErrorAt(label_, element,
                          "count=\"" + std::to_string(count) + "\" but the text holds " +
                              (values.size() > static_cast<std::size_t>(count) ? "more" : std::to_string(values.size())) + " values");
    }
    return values;
  }

  Expected<MlaDistortion> Distortion(const XMLElement* root) {
    MlaDistortion distortion;  // absent: constant, no parameters, centre 0
    const XMLElement* element = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(element, xml::OptionalUniqueChild(label_, root, "distortion"));
    if (element == nullptr) return distortion;
    Remember(element);
    LIFMCR_XML_ASSIGN_OR_RETURN(distortion.type, xml::RequiredAttribute(label_, element, "type"));
    const XMLElement* function = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(function, xml::UniqueChild(label_, element, "function"));
    Remember(function);
    distortion.function = function->GetText() != nullptr ? function->GetText() : "";
    const XMLElement* parameter = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(parameter, xml::UniqueChild(label_, element, "parameter"));
    Remember(parameter);
    LIFMCR_XML_ASSIGN_OR_RETURN(distortion.parameters, Parameters(parameter));
    LIFMCR_XML_ASSIGN_OR_RETURN(distortion.offset_px, Vector(element, "offset", "pix"));
    return distortion;
  }

  Expected<std::array<MlaLensType, 3>> LensTypes(const XMLElement* root) {
    const std::vector<const XMLElement*> elements = xml::Children(root, "lens_type");
    if (elements.size() != 3) {
      return xml::ErrorAt(label_, elements.size() > 3 ? elements[3] : root,
                          "expected exactly three <lens_type> elements (ids 0, 1, 2), found " +
                              std::to_string(elements.size()));
    }
    std::array<MlaLensType, 3> types{};
    std::array<const XMLElement*, 3> seen{};
    for (const XMLElement* element : elements) {
      LIFMCR_XML_ASSIGN_OR_RETURN(const std::string id_text,
                                  xml::RequiredAttribute(label_, element, "id"));
      int id = -1;
      if (!xml::ParseStrictInt(id_text, &id) || id < 0 || id > 2) {
        return xml::ErrorAt(label_, element,
                            "expected lens_type id 0, 1 or 2, got \"" + Excerpt(id_text) + "\"");
      }
      if (seen[id] != nullptr) {
        return xml::ErrorAt(label_, element,
                            "duplicate lens_type id " + std::to_string(id) + " (first at line " +
                                std::to_string(seen[id]->GetLineNum()) + ")");
      }
      seen[id] = element;
      Remember(element);
      MlaLensType& type = types[id];
      type.id = id;
      LIFMCR_XML_ASSIGN_OR_RETURN(type.offset_lens, Vector(element, "offset", "lens"));
      const XMLElement* range = nullptr;
      LIFMCR_XML_ASSIGN_OR_RETURN(range, xml::UniqueChild(label_, element, "depth_range"));
      Remember(range);
      LIFMCR_XML_RETURN_IF_ERROR(CheckUnits(range, "virtual_depth"));
      LIFMCR_XML_ASSIGN_OR_RETURN(type.depth_min, Number(range, "min"));
      LIFMCR_XML_ASSIGN_OR_RETURN(type.depth_max, Number(range, "max"));
    }
    return types;
  }

  std::string label_;
  // Elements by path, so that a failed check on the finished calibration
  // can still name the line it came from.
  std::map<std::string, const XMLElement*> elements_;
};

// ---------------------------------------------------------------- writing

// "%.12f" as RxLive writes, unless that loses more than 1e-12 relative.
std::string FormatNumber(double value) {
  char buffer[400];
  const auto result =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::fixed, 12);
  if (result.ec == std::errc()) {
    std::string fixed(buffer, result.ptr);
    double back = 0.0;
    if (xml::ParseStrictDouble(fixed, &back) && std::abs(back - value) <= 1e-12 * std::abs(value)) {
      return fixed;
    }
  }
  return xml::FormatShortest(value);
}

class Writer {
 public:
  std::string Take() { return std::move(out_); }

  void Line(int depth, const std::string& text) {
    if (!out_.empty()) out_ += "\r\n";
    out_.append(2 * depth, ' ');
    out_ += text;
  }
  void Scalar(int depth, const std::string& name, const char* units, double value) {
    Line(depth, "<" + name + " units=\"" + units + "\">" + FormatNumber(value) + "</" + name + ">");
  }
  void Leaf(int depth, const std::string& name, double value) {
    Line(depth, "<" + name + ">" + FormatNumber(value) + "</" + name + ">");
  }
  void Vector(int depth, const std::string& name, const char* units, const Eigen::Vector2d& v) {
    Line(depth, "<" + name + " units=\"" + units + "\">");
    Leaf(depth + 1, "x", v.x());
    Leaf(depth + 1, "y", v.y());
    Line(depth, "</" + name + ">");
  }

 private:
  std::string out_;
};

}  // namespace

Status CheckMlaCalibration(const MlaCalibration& calibration) {
  if (const std::optional<MlaProblem> problem = FindProblem(calibration)) {
    return MakeErrorAt("MlaCalibration", problem->path, problem->what);
  }
  return Status::Ok();
}

Expected<MlaCalibration> ParseMlaXml(std::string_view text, const std::string& file_label) {
  return Reader(file_label).Read(text);
}

Expected<MlaCalibration> ReadMlaXml(const std::filesystem::path& path) {
  LIFMCR_XML_ASSIGN_OR_RETURN(
      const std::string text,
      xml::ReadTextFile(path, {"an MLA calibration XML (RayCalibData 1.0)", kMlaLimits.max_file_bytes}));
  return ParseMlaXml(text, EscapeText(path.string()));
}

std::string FormatMlaXml(const MlaCalibration& c) {
  Writer w;
  w.Line(0, "<RayCalibData version=\"" + xml::EscapeXml(c.version) + "\">");
  w.Vector(1, "offset", "pix", c.offset_px);
  w.Scalar(1, "diameter", "pix", c.diameter_px);
  w.Scalar(1, "rotation", "rad", c.rotation_rad);
  w.Scalar(1, "lens_border", "pix", c.lens_border_px);
  w.Scalar(1, "tcp", "virtual_depth", c.tcp_virtual_depth);
  w.Vector(1, "lens_base_x", "lens", c.lens_base_x);
  w.Vector(1, "lens_base_y", "lens", c.lens_base_y);
  w.Vector(1, "sub_grid_base", "lens", c.sub_grid_base);
  w.Line(1, "<distortion type=\"" + xml::EscapeXml(c.distortion.type) + "\">");
  w.Line(2, "<function>" + xml::EscapeXml(c.distortion.function) + "</function>");
  std::string parameters;
  for (double p : c.distortion.parameters) {
    parameters += (parameters.empty() ? "" : ";") + FormatNumber(p);
  }
  if (parameters.empty()) parameters = "0";  // RxLive's text for an empty list
  w.Line(2, "<parameter count=\"" + std::to_string(c.distortion.parameters.size()) + "\">" +
                parameters + "</parameter>");
  w.Vector(2, "offset", "pix", c.distortion.offset_px);
  w.Line(1, "</distortion>");
  for (const MlaLensType& type : c.lens_types) {
    w.Line(1, "<lens_type id=\"" + std::to_string(type.id) + "\">");
    w.Vector(2, "offset", "lens", type.offset_lens);
    w.Line(2, "<depth_range units=\"virtual_depth\">");
    w.Leaf(3, "min", type.depth_min);
    w.Leaf(3, "max", type.depth_max);
    w.Line(2, "</depth_range>");
    w.Line(1, "</lens_type>");
  }
  w.Line(0, "</RayCalibData>");
  return w.Take();
}

Status WriteMlaXml(const std::filesystem::path& path, const MlaCalibration& calibration) {
  if (const std::optional<MlaProblem> problem = FindProblem(calibration)) {
    return MakeErrorAt(path.string(), problem->path, "not written: " + problem->what);
  }
  return xml::WriteTextFile(path, FormatMlaXml(calibration));
}

}  // namespace lifmcr
