#include "replay/vsk.h"

#include "config/text_escape.h"
#include "replay/xml_util.h"

#include <tinyxml2.h>

#include <cmath>
#include <set>
#include <unordered_map>
#include <sstream>
#include <utility>

namespace lifmcr {
namespace {

using tinyxml2::XMLElement;

// VERSION as Tracker ("3.2") and Nexus ("2.5") write it: numbers joined by '.'.
bool IsVersionNumber(std::string_view text) {
  if (text.empty() || text.size() > 16) return false;
  bool digit_before = false;
  for (char c : text) {
    if (c == '.') {
      if (!digit_before) return false;
      digit_before = false;
    } else if (c >= '0' && c <= '9') {
      digit_before = true;
    } else {
      return false;
    }
  }
  return digit_before;
}

bool IsNameStart(char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_'; }

std::vector<std::string> SplitWhitespace(std::string_view text) {
  std::vector<std::string> tokens;
  std::istringstream in{std::string(text)};
  for (std::string token; in >> token;) tokens.push_back(token);
  return tokens;
}

// ---------------------------------------------------------------- reading

class Reader {
 public:
  explicit Reader(std::string label) : label_(std::move(label)) {}

  Expected<Vsk> Read(std::string_view text) {
    tinyxml2::XMLDocument doc;
    LIFMCR_XML_RETURN_IF_ERROR(xml::ParseDocument(text, label_, &doc));
    const XMLElement* root = doc.RootElement();
    if (std::string_view(root->Name()) != "KinematicModel") {
      return xml::ErrorAt(label_, root,
                          "root element is <" + Excerpt(root->Name()) +
                              ">, expected <KinematicModel> (a Vicon .vsk subject model)");
    }
    LIFMCR_XML_ASSIGN_OR_RETURN(vsk_.version, xml::RequiredAttribute(label_, root, "VERSION"));
    if (!IsVersionNumber(vsk_.version)) {
      return xml::ErrorAt(label_, root,
                          "VERSION is '" + Excerpt(vsk_.version) +
                              "', expected a version number such as 3.2 (Tracker) or 2.5 (Nexus)");
    }
    if (const char* model = root->Attribute("MODEL")) vsk_.model = model;

    const XMLElement* parameters = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(parameters, xml::OptionalUniqueChild(label_, root, "Parameters"));
    if (parameters != nullptr) LIFMCR_XML_RETURN_IF_ERROR(ReadParameters(parameters));

    // A model without a segment has no subject to track and no frame its
    // markers could be in: not a model a capture can use.
    const XMLElement* skeleton = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(skeleton, xml::UniqueChild(label_, root, "Skeleton"));
    LIFMCR_XML_RETURN_IF_ERROR(ReadSegments(skeleton, "", 1));
    if (vsk_.segments.empty()) {
      return xml::ErrorAt(label_, skeleton,
                          "no <Segment>; expected at least one (each root segment is a subject)");
    }

    const XMLElement* marker_set = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(marker_set, xml::OptionalUniqueChild(label_, root, "MarkerSet"));
    const XMLElement* markers = nullptr;
    if (marker_set != nullptr) {
      LIFMCR_XML_ASSIGN_OR_RETURN(markers, xml::OptionalUniqueChild(label_, marker_set, "Markers"));
    }
    std::vector<const XMLElement*> marker_elements;
    if (markers != nullptr) marker_elements = xml::Children(markers, "Marker");
    if (marker_elements.size() > kVskLimits.max_markers) {
      return xml::ErrorAt(label_, marker_elements[kVskLimits.max_markers],
                          "more than " + std::to_string(kVskLimits.max_markers) +
                              " markers; expected the markers of real Vicon subjects");
    }
    for (const XMLElement* element : marker_elements) {
      LIFMCR_XML_ASSIGN_OR_RETURN(const std::string name, Name(element, "marker"));
      if (const auto first = marker_at_.find(name); first != marker_at_.end()) {
        return xml::ErrorAt(label_, element,
                            "duplicate marker '" + Excerpt(name) + "' (first at line " +
                                std::to_string(first->second->GetLineNum()) + ")");
      }
      marker_at_[name] = element;
    }

    const XMLElement* target_set = nullptr;
    LIFMCR_XML_ASSIGN_OR_RETURN(target_set, xml::OptionalUniqueChild(label_, root, "TargetSet"));
    const XMLElement* targets = nullptr;
    if (target_set != nullptr) {
      LIFMCR_XML_ASSIGN_OR_RETURN(targets, xml::OptionalUniqueChild(label_, target_set, "Targets"));
    }
    if (targets != nullptr) {
      for (const XMLElement* target : xml::Children(targets, "TargetLocalPointToWorldPoint")) {
        LIFMCR_XML_ASSIGN_OR_RETURN(const std::string marker,
                                    xml::RequiredAttribute(label_, target, "MARKER"));
        if (marker_at_.count(marker) == 0) {
          return xml::ErrorAt(
              label_, target,
              "target refers to marker '" + Excerpt(marker) + "', which is not in <MarkerSet><Markers>");
        }
        if (const auto first = target_of_.find(marker); first != target_of_.end()) {
          return xml::ErrorAt(label_, target,
                              "duplicate target for marker '" + Excerpt(marker) + "' (first at line " +
                                  std::to_string(first->second->GetLineNum()) + ")");
        }
        target_of_[marker] = target;
      }
    }

    for (const XMLElement* element : marker_elements) {
      LIFMCR_XML_RETURN_IF_ERROR(ReadMarker(element));
    }
    return std::move(vsk_);
  }

 private:
  // The NAME of a segment, marker or parameter: other elements and the
  // Vicon stream refer to it, so an empty or blank one names nothing.
  Expected<std::string> Name(const XMLElement* element, const char* kind) {
    LIFMCR_XML_ASSIGN_OR_RETURN(std::string name, xml::RequiredAttribute(label_, element, "NAME"));
    if (name.find_first_not_of(" \t\r\n") == std::string::npos) {
      return xml::ErrorAt(label_, element,
                          std::string("empty ") + kind + " NAME; expected the " + kind +
                              "'s name (other elements refer to it)");
    }
    return name;
  }

  Status ReadParameters(const XMLElement* parameters) {
    for (const XMLElement* element = parameters->FirstChildElement(); element != nullptr;
         element = element->NextSiblingElement()) {
      const std::string_view kind = element->Name();
      if (kind != "Parameter" && kind != "StaticParameter") continue;
      LIFMCR_XML_ASSIGN_OR_RETURN(const std::string name, Name(element, "parameter"));
      if (const auto first = parameter_at_.find(name); first != parameter_at_.end()) {
        return xml::ErrorAt(label_, element,
                            "duplicate parameter '" + Excerpt(name) + "' (first at line " +
                                std::to_string(first->second->GetLineNum()) + ")");
      }
      if (parameter_at_.size() >= kVskLimits.max_parameters) {
        return xml::ErrorAt(label_, element,
                            "more than " + std::to_string(kVskLimits.max_parameters) +
                                " parameters; expected the model of real Vicon subjects");
      }
      parameter_at_[name] = element;
      const char* value_text = element->Attribute("VALUE");
      if (value_text == nullptr) continue;  // EXPRESSION only: not evaluated
      double value = 0.0;
      if (!xml::ParseStrictDouble(value_text, &value)) {
        return xml::ErrorAt(
            label_, element,
            "parameter '" + Excerpt(name) + "': expected a number in VALUE, got '" +
                Excerpt(value_text) + "'");
      }
      vsk_.parameters[name] = value;
    }
    return Status::Ok();
  }

  // Pre-order walk, so parents come before their children.
  // DEPTH: that of the segments read here (a root segment is 1 deep).
  Status ReadSegments(const XMLElement* parent_element, const std::string& parent,
                      std::size_t depth) {
    for (const XMLElement* element : xml::Children(parent_element, "Segment")) {
      if (depth > kVskLimits.max_segment_depth) {
        return xml::ErrorAt(label_, element,
                            "segments nested more than " +
                                std::to_string(kVskLimits.max_segment_depth) +
                                " deep; expected the model of real Vicon subjects");
      }
      LIFMCR_XML_ASSIGN_OR_RETURN(const std::string name, Name(element, "segment"));
      if (const auto first = segment_at_.find(name); first != segment_at_.end()) {
        return xml::ErrorAt(label_, element,
                            "duplicate segment '" + Excerpt(name) + "' (first at line " +
                                std::to_string(first->second->GetLineNum()) + ")");
      }
      if (vsk_.segments.size() >= kVskLimits.max_segments) {
        return xml::ErrorAt(label_, element,
                            "more than " + std::to_string(kVskLimits.max_segments) +
                                " segments; expected the model of real Vicon subjects");
      }
      segment_at_[name] = element;
      vsk_.segments.push_back(VskSegment{name, parent});
      LIFMCR_XML_RETURN_IF_ERROR(ReadSegments(element, name, depth + 1));
    }
    return Status::Ok();
  }

  // One POSITION component: a number, or a parameter name (quoted in v3.x,
  // possibly with a sign prefix in v2.5).
  Expected<double> Component(const XMLElement* element, const std::string& marker,
                             std::string token) {
    const bool quoted = token.size() >= 2 && token.front() == '\'' && token.back() == '\'';
    if (quoted) token = token.substr(1, token.size() - 2);
    double value = 0.0;
    if (xml::ParseStrictDouble(token, &value)) return value;
    if (const auto it = vsk_.parameters.find(token); it != vsk_.parameters.end()) {
      return it->second;
    }
    const bool signed_name = !token.empty() && (token.front() == '-' || token.front() == '+');
    const std::string name = signed_name ? token.substr(1) : token;
    if (const auto it = vsk_.parameters.find(name); signed_name && it != vsk_.parameters.end()) {
      return token.front() == '-' ? -it->second : it->second;
    }
    if (!quoted && (name.empty() || !IsNameStart(name.front()))) {
      return xml::ErrorAt(label_, element,
                          "marker " + Excerpt(marker) + ": POSITION component '" + Excerpt(token) +
                              "' is neither a number nor a parameter name");
    }
    if (parameter_at_.count(name) != 0) {
      return xml::ErrorAt(label_, element,
                          "marker " + Excerpt(marker) + " references parameter '" + Excerpt(name) +
                              "', which has no VALUE (EXPRESSION parameters are not evaluated)");
    }
    return xml::ErrorAt(label_, element,
                        "marker " + Excerpt(marker) + " references undefined parameter '" +
                            Excerpt(name) + "'");
  }

  Expected<Eigen::Vector3d> Position(const XMLElement* element, const std::string& marker) {
    const char* text = element->Attribute("POSITION");
    const std::vector<std::string> tokens = SplitWhitespace(text != nullptr ? text : "");
    if (tokens.size() != 3) {
      return xml::ErrorAt(label_, element,
                          "marker " + Excerpt(marker) + ": expected POSITION with 3 components, got " +
                              std::to_string(tokens.size()) + ": \"" + Excerpt(text ? text : "") +
                              "\"");
    }
    Eigen::Vector3d position;
    for (int i = 0; i < 3; ++i) {
      LIFMCR_XML_ASSIGN_OR_RETURN(position[i], Component(element, marker, tokens[i]));
    }
    if (position.cwiseAbs().maxCoeff() > kVskLimits.max_abs_position_mm) {
      return xml::ErrorAt(label_, element,
                          "marker " + Excerpt(marker) + ": position (" +
                              xml::FormatShortest(position.x()) + ", " +
                              xml::FormatShortest(position.y()) + ", " +
                              xml::FormatShortest(position.z()) +
                              ") mm, expected each coordinate within +-" +
                              xml::FormatShortest(kVskLimits.max_abs_position_mm) +
                              " mm of its segment (a real capture volume)");
    }
    return position;
  }

  Status ReadMarker(const XMLElement* element) {
    VskMarker marker;
    marker.name = element->Attribute("NAME");
    if (const char* status = element->Attribute("STATUS")) marker.status = status;
    if (const char* radius = element->Attribute("RADIUS")) {
      if (!xml::ParseStrictDouble(radius, &marker.radius_mm) || marker.radius_mm < 0 ||
          marker.radius_mm > kVskLimits.max_radius_mm) {
        return xml::ErrorAt(label_, element,
                            "marker " + Excerpt(marker.name) + ": expected RADIUS 0 .. " +
                                xml::FormatShortest(kVskLimits.max_radius_mm) + " mm, got '" +
                                Excerpt(radius) + "'");
      }
    }
    // v3.x: the target holds segment and position; v2.5: the marker itself.
    const auto target = target_of_.find(marker.name);
    const XMLElement* source = target != target_of_.end() ? target->second : element;
    if (source->Attribute("POSITION") == nullptr) {
      return xml::ErrorAt(label_, element,
                          "marker " + Excerpt(marker.name) +
                              " has no position: neither a POSITION attribute nor a "
                              "TargetLocalPointToWorldPoint");
    }
    const char* segment = source->Attribute("SEGMENT");
    if (segment == nullptr) {
      return xml::ErrorAt(label_, source,
                          "marker " + Excerpt(marker.name) + ": missing attribute SEGMENT");
    }
    marker.segment = segment;
    if (segment_at_.count(marker.segment) == 0) {
      return xml::ErrorAt(label_, source,
                          "marker " + Excerpt(marker.name) + " refers to segment '" +
                              Excerpt(marker.segment) + "', which is not in <Skeleton>");
    }
    LIFMCR_XML_ASSIGN_OR_RETURN(marker.position_mm, Position(source, marker.name));
    vsk_.markers.push_back(std::move(marker));
    return Status::Ok();
  }

  std::string label_;
  Vsk vsk_;
  std::map<std::string, const XMLElement*> parameter_at_;
  std::map<std::string, const XMLElement*> segment_at_;
  std::map<std::string, const XMLElement*> marker_at_;
  std::map<std::string, const XMLElement*> target_of_;  // marker name -> its target
};

// ---------------------------------------------------------------- writing

// Names end up inside POSITION="'a' 'b' 'c'", so no whitespace or quotes.
Status CheckWritableName(const std::string& kind, const std::string& name) {
  if (name.empty()) return Error{"VSK: cannot write a " + kind + " with an empty name"};
  for (char c : name) {
    if (c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\'' || c == '"') {
      return Error{"VSK: cannot write " + kind + " '" + name +
                   "': names must not contain whitespace or quotes"};
    }
  }
  return Status::Ok();
}

constexpr char kCovariance6[] =
    "2.464900016784668 0 0 0 0 0 0 2.464900016784668 0 0 0 0 0 0 246.49000549316406 0 0 0 0 0 0 "
    "1000000 0 0 0 0 0 0 1000000 0 0 0 0 0 0 1000000";
constexpr char kIdentity3[] = "1 0 0 0 1 0 0 0 1";

class Writer {
 public:
  explicit Writer(const Vsk& vsk) : vsk_(vsk) {}

  Expected<std::string> Format() {
    LIFMCR_XML_RETURN_IF_ERROR(Check());
    const std::string version = vsk_.version.rfind("3.", 0) == 0 ? vsk_.version : "3.2";
    Line(0, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    std::string root = "<KinematicModel VERSION=\"" + xml::EscapeXml(version) + "\"";
    if (!vsk_.model.empty()) root += " MODEL=\"" + xml::EscapeXml(vsk_.model) + "\"";
    Line(0, root + ">");

    Line(1, "<Parameters>");
    std::set<std::string> generated;
    for (const VskMarker& marker : vsk_.markers) {
      for (int axis = 0; axis < 3; ++axis) {
        const std::string name = ParameterName(marker, axis);
        generated.insert(name);
        const std::string value = xml::FormatShortest(marker.position_mm[axis]);
        Line(2, "<Parameter NAME=\"" + xml::EscapeXml(name) + "\" VALUE=\"" + value +
                    "\" PRIOR=\"" + value + "\" HIDDEN=\"true\" />");
      }
    }
    for (const auto& [name, value] : vsk_.parameters) {
      if (generated.count(name) != 0) continue;  // the marker's position wins
      const std::string text = xml::FormatShortest(value);
      Line(2, "<Parameter NAME=\"" + xml::EscapeXml(name) + "\" VALUE=\"" + text + "\" PRIOR=\"" +
                  text + "\" HIDDEN=\"false\" />");
    }
    Line(1, "</Parameters>");

    Line(1, "<Skeleton>");
    // Children by parent, indexed once: the walk below visits each segment
    // once (a scan of every segment per segment was quadratic).
    std::unordered_map<std::string_view, std::vector<const VskSegment*>> children;
    for (const VskSegment& segment : vsk_.segments) {
      children[segment.parent].push_back(&segment);
    }
    for (const VskSegment* root : children[""]) WriteSegment(2, *root, children);
    Line(1, "</Skeleton>");

    Line(1, "<MarkerSet>");
    Line(2, "<Markers>");
    for (const VskMarker& marker : vsk_.markers) {
      std::string line = "<Marker NAME=\"" + xml::EscapeXml(marker.name) + "\" RADIUS=\"" +
                         xml::FormatShortest(marker.radius_mm) + "\" RGB=\"255 164 0\"";
      if (!marker.status.empty()) line += " STATUS=\"" + xml::EscapeXml(marker.status) + "\"";
      Line(3, line + " VIEW-ANGLE=\"0\" />");
    }
    Line(2, "</Markers>");
    Line(1, "</MarkerSet>");

    Line(1, "<TargetSet>");
    Line(2, "<Targets>");
    for (const VskMarker& marker : vsk_.markers) {
      Line(3, std::string("<TargetLocalPointToWorldPoint COVARIANCE=\"") + kIdentity3 +
                  "\" FILL-GAPS=\"false\" GAUSSIAN=\"true\" HIDDEN=\"false\" MARKER=\"" +
                  xml::EscapeXml(marker.name) + "\" OPACITY=\"255\" POSITION=\"'" +
                  xml::EscapeXml(ParameterName(marker, 0)) + "' '" +
                  xml::EscapeXml(ParameterName(marker, 1)) + "' '" +
                  xml::EscapeXml(ParameterName(marker, 2)) + "'\" RGB=\"93 93 93\" SEGMENT=\"" +
                  xml::EscapeXml(marker.segment) + "\" WEIGHT=\"1\" DRAW-STYLE=\"None\">");
      Line(4, std::string("<TargetLocalPointToWorldPointTemplate COVARIANCE=\"") + kIdentity3 +
                  "\" />");
      Line(3, "</TargetLocalPointToWorldPoint>");
    }
    Line(2, "</Targets>");
    Line(1, "</TargetSet>");
    Line(0, "</KinematicModel>");
    return std::move(out_);
  }

 private:
  static std::string ParameterName(const VskMarker& marker, int axis) {
    static constexpr const char* kAxes[] = {"x", "y", "z"};
    return marker.segment + "_" + marker.name + "_" + kAxes[axis];
  }

  Status Check() const {
    // What ReadVsk accepts, so that every file written reads back.
    if (vsk_.segments.size() > kVskLimits.max_segments ||
        vsk_.markers.size() > kVskLimits.max_markers ||
        vsk_.parameters.size() + 3 * vsk_.markers.size() > kVskLimits.max_parameters) {
      return Error{"VSK: cannot write " + std::to_string(vsk_.segments.size()) + " segments, " +
                   std::to_string(vsk_.markers.size()) + " markers and " +
                   std::to_string(vsk_.parameters.size()) + " parameters; at most " +
                   std::to_string(kVskLimits.max_segments) + ", " +
                   std::to_string(kVskLimits.max_markers) + " and " +
                   std::to_string(kVskLimits.max_parameters) + " with 3 per marker are read"};
    }
    if (vsk_.segments.empty()) return Error{"VSK: cannot write a model without segments"};
    std::unordered_map<std::string_view, std::size_t> depth_of;  // a root segment is 1 deep
    for (const VskSegment& segment : vsk_.segments) {
      LIFMCR_XML_RETURN_IF_ERROR(CheckWritableName("segment", segment.name));
      std::size_t depth = 1;
      if (!segment.parent.empty()) {
        const auto parent = depth_of.find(segment.parent);
        if (parent == depth_of.end()) {
          return Error{"VSK: cannot write segment '" + segment.name + "': its parent '" +
                       segment.parent + "' is not a segment listed before it"};
        }
        depth = parent->second + 1;
      }
      if (depth > kVskLimits.max_segment_depth) {
        return Error{"VSK: cannot write segment '" + segment.name + "': nested " +
                     std::to_string(depth) + " segments deep; at most " +
                     std::to_string(kVskLimits.max_segment_depth) + " are read"};
      }
      if (!depth_of.emplace(segment.name, depth).second) {
        return Error{"VSK: cannot write duplicate segment '" + segment.name + "'"};
      }
    }
    std::set<std::string> markers;
    std::set<std::string> generated;
    for (const VskMarker& marker : vsk_.markers) {
      LIFMCR_XML_RETURN_IF_ERROR(CheckWritableName("marker", marker.name));
      if (!markers.insert(marker.name).second) {
        return Error{"VSK: cannot write duplicate marker '" + marker.name + "'"};
      }
      if (depth_of.count(marker.segment) == 0) {
        return Error{"VSK: cannot write marker '" + marker.name + "': its segment '" +
                     marker.segment + "' is not in the segments"};
      }
      if (!marker.position_mm.allFinite() || !std::isfinite(marker.radius_mm)) {
        return Error{"VSK: cannot write marker '" + marker.name +
                     "': position or radius is not finite"};
      }
      for (int axis = 0; axis < 3; ++axis) {
        if (!generated.insert(ParameterName(marker, axis)).second) {
          return Error{"VSK: cannot write marker '" + marker.name + "': parameter name '" +
                       ParameterName(marker, axis) + "' is generated twice"};
        }
      }
    }
    for (const auto& [name, value] : vsk_.parameters) {
      LIFMCR_XML_RETURN_IF_ERROR(CheckWritableName("parameter", name));
      if (!std::isfinite(value)) {
        return Error{"VSK: cannot write parameter '" + name + "': value is not finite"};
      }
    }
    return Status::Ok();
  }

  // Recursion depth is the segment chain's, at most kVskLimits.max_segment_depth (Check).
  void WriteSegment(
      int depth, const VskSegment& segment,
      const std::unordered_map<std::string_view, std::vector<const VskSegment*>>& children) {
    const std::string name = xml::EscapeXml(segment.name);
    const std::string joint =
        (segment.parent.empty() ? std::string("World") : xml::EscapeXml(segment.parent)) + "_" +
        name;
    Line(depth, "<Segment NAME=\"" + name +
                    "\" OPACITY=\"255\" BOUNDS=\"-50 -50 -50 50 50 50\" MASS=\"0\" "
                    "MASS-CENTRE=\"0 0 0\" INERTIA=\"0 0 0\" RGB=\"255 164 0\" HIDDEN=\"false\">");
    Line(depth + 1, "<JointFree NAME=\"" + joint +
                        "\" PRE-ORIENTATION=\"0 0 0\" PRE-POSITION=\"0 0 0\" "
                        "INVERSE-POST-ORIENTATION=\"0 0 0\" INVERSE-POST-POSITION=\"0 0 0\" "
                        "MEAN=\"0 0 0 0 0 0\" COVARIANCE=\"" +
                        kCovariance6 + "\" T=\"* * * * * *\" SIGNS=\"+ + + + + +\">");
    Line(depth + 2, std::string("<JointTemplate MEAN=\"0 0 0 0 0 0\" COVARIANCE=\"") +
                        kCovariance6 + "\" PRE-ORIENTATION=\"0 0 0\" PRE-POSITION=\"0 0 0\" />");
    Line(depth + 1, "</JointFree>");
    if (const auto found = children.find(segment.name); found != children.end()) {
      for (const VskSegment* child : found->second) WriteSegment(depth + 1, *child, children);
    }
    Line(depth, "</Segment>");
  }

  void Line(int depth, const std::string& text) {
    out_.append(depth, '\t');
    out_ += text;
    out_ += '\n';
  }

  const Vsk& vsk_;
  std::string out_;
};

}  // namespace

std::vector<std::string> VskSubjects(const Vsk& vsk) {
  std::vector<std::string> subjects;
  for (const VskSegment& segment : vsk.segments) {
    if (segment.parent.empty()) subjects.push_back(segment.name);
  }
  return subjects;
}

std::vector<VskMarker> VskMarkersOfSegment(const Vsk& vsk, std::string_view segment) {
  std::vector<VskMarker> markers;
  for (const VskMarker& marker : vsk.markers) {
    if (marker.segment == segment) markers.push_back(marker);
  }
  return markers;
}

namespace {

// The root segment (subject) of every segment: parents are followed with a
// memo, so each segment is visited a constant number of times whatever the
// order of `segments`; a parent cycle (only possible in a Vsk built in
// code) or a missing parent leaves the segment without a subject.
std::unordered_map<std::string, std::string> SubjectOfSegments(const Vsk& vsk) {
  std::unordered_map<std::string, const VskSegment*> by_name;
  for (const VskSegment& segment : vsk.segments) by_name.emplace(segment.name, &segment);
  std::unordered_map<std::string, std::string> subject_of;
  for (const VskSegment& segment : vsk.segments) {
    std::vector<const VskSegment*> chain;
    const VskSegment* at = &segment;
    std::string root;
    while (true) {
      if (const auto known = subject_of.find(at->name); known != subject_of.end()) {
        root = known->second;
        break;
      }
      if (at->parent.empty()) {
        root = at->name;
        chain.push_back(at);
        break;
      }
      chain.push_back(at);
      const auto parent = by_name.find(at->parent);
      if (parent == by_name.end() || chain.size() > vsk.segments.size()) break;
      at = parent->second;
    }
    for (const VskSegment* s : chain) subject_of.emplace(s->name, root);
  }
  return subject_of;
}

}  // namespace

std::vector<VskMarker> VskMarkersOfSubject(const Vsk& vsk, std::string_view subject) {
  // Each marker's segment chain up to its root: O(markers x depth), the
  // depth bounded by the XML nesting limit for files read.
  std::unordered_map<std::string_view, std::string_view> parent_of;
  for (const VskSegment& segment : vsk.segments) parent_of.emplace(segment.name, segment.parent);
  std::vector<VskMarker> markers;
  for (const VskMarker& marker : vsk.markers) {
    std::string_view at = marker.segment;
    for (std::size_t steps = 0; steps <= vsk.segments.size(); ++steps) {
      if (at == subject) {
        markers.push_back(marker);
        break;
      }
      const auto parent = parent_of.find(at);
      if (parent == parent_of.end() || parent->second.empty()) break;
      at = parent->second;
    }
  }
  return markers;
}

std::vector<std::pair<std::string, std::vector<VskMarker>>> VskMarkersBySubject(const Vsk& vsk) {
  const std::unordered_map<std::string, std::string> subject_of = SubjectOfSegments(vsk);
  std::vector<std::pair<std::string, std::vector<VskMarker>>> result;
  std::unordered_map<std::string, std::size_t> index;
  for (const std::string& subject : VskSubjects(vsk)) {
    index.emplace(subject, result.size());
    result.emplace_back(subject, std::vector<VskMarker>{});
  }
  for (const VskMarker& marker : vsk.markers) {
    const auto it = subject_of.find(marker.segment);
    if (it == subject_of.end()) continue;
    const auto at = index.find(it->second);
    if (at != index.end()) result[at->second].second.push_back(marker);
  }
  return result;
}

Expected<Eigen::Vector3d> VskMarkerCentroidMm(const Vsk& vsk, std::string_view segment) {
  const std::vector<VskMarker> markers = VskMarkersOfSegment(vsk, segment);
  if (markers.empty()) {
    return Error{"VSK: segment '" + std::string(segment) + "' has no markers"};
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const VskMarker& marker : markers) sum += marker.position_mm;
  return Eigen::Vector3d(sum / static_cast<double>(markers.size()));
}

Expected<Vsk> ParseVsk(std::string_view text, const std::string& file_label) {
  return Reader(file_label).Read(text);
}

Expected<Vsk> ReadVsk(const std::filesystem::path& path) {
  LIFMCR_XML_ASSIGN_OR_RETURN(
      const std::string text,
      xml::ReadTextFile(path, {"a Vicon model (.vsk, <KinematicModel>)", kVskLimits.max_file_bytes}));
  return ParseVsk(text, EscapeText(path.string()));
}

Expected<std::string> FormatVsk(const Vsk& vsk) { return Writer(vsk).Format(); }

Status WriteVsk(const std::filesystem::path& path, const Vsk& vsk) {
  auto text = FormatVsk(vsk);
  if (!text.ok()) return Error{path.string() + ": not written: " + text.error().message};
  return xml::WriteTextFile(path, *text);
}

}  // namespace lifmcr
