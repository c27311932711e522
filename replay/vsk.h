#pragma once
// Vicon .vsk subject/object models (XML, root <KinematicModel>;
// as Vicon Nexus and Tracker write them). LiFMCR's Calibration/03_Vicon/Object.vsk holds
// the marker clusters of cam0, cam2 and the reference plate.
//
// Two layouts are read:
//  * Tracker v3.x: a marker's position is three parameter names,
//      <TargetLocalPointToWorldPoint MARKER="Go21" SEGMENT="Go2"
//                                    POSITION="'Go2_Go21_x' 'Go2_Go21_y' 'Go2_Go21_z'"/>
//    resolved through <Parameters><Parameter NAME=… VALUE=…/>.
//  * Nexus v2.5: inline <Marker NAME="LFHD" SEGMENT="Head" POSITION="0 70.3721 0"/>,
//    where each component is a number or a parameter name with an optional
//    sign prefix ("-ASISy").
// A marker with a TargetLocalPointToWorldPoint takes its position from it;
// otherwise from its own POSITION. Parameters given only by an EXPRESSION are
// not evaluated: referring to one is an error that says so.
//
// Subjects: a file may hold several (LiFMCR's Object.vsk has three). Each
// root <Segment> of the <Skeleton> is one subject; nested segments form
// its hierarchy (Nexus). Marker positions are in millimetres in the frame of
// their segment.
//
// Checks beyond the layout: VERSION is present and a version number ("3.2",
// "2.5"); the <Skeleton> holds at least one segment (a model without one
// tracks nothing); segment, marker and parameter NAMEs are not empty.
//
// Limits (kVskLimits; README, "Limits of every input"): the file size, and
// marker positions and radii a real capture volume can hold. Reading and the
// subject queries below are O(n log n) in the file.
//
// Errors name the file, the line and the element path, e.g.
//   "Object.vsk:97: /KinematicModel/TargetSet/Targets/TargetLocalPointToWorldPoint[@MARKER='Go21']:
//    marker Go21 references undefined parameter 'Go2_Go21_y'".

#include "config/error.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lifmcr {

struct VskLimits {
  std::uint64_t max_file_bytes = 16u << 20;  // real files: 10-100 KB
  double max_abs_position_mm = 100000;       // 100 m: larger than any capture volume
  double max_radius_mm = 1000;               // real markers: 3-25 mm
  std::size_t max_segments = 10000;          // real: 1-20 per subject, tens of subjects
  // A root segment is 1 deep. Bounded by the XML reader's element nesting
  // (tinyxml2: 100, each segment one level inside KinematicModel/Skeleton);
  // real skeletons are under 20 deep.
  std::size_t max_segment_depth = 64;
  std::size_t max_markers = 10000;
  std::size_t max_parameters = 100000;
};
inline constexpr VskLimits kVskLimits{};

struct VskMarker {
  std::string name;     // unique in the file
  std::string segment;  // the segment whose frame position_mm is in
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  std::string status;      // "required", "optional", or "" when the file gives none
  double radius_mm = 0.0;  // 0 when the file gives none
};

struct VskSegment {
  std::string name;    // unique in the file
  std::string parent;  // "" for a root segment (a subject)
};

struct Vsk {
  std::string version;               // VERSION attribute, e.g. "3.2" or "2.5"
  std::string model;                 // MODEL attribute, "" when absent
  std::vector<VskSegment> segments;  // parents before children
  std::vector<VskMarker> markers;    // file order
  // Every parameter with a numeric VALUE (Parameter and StaticParameter).
  std::map<std::string, double> parameters;
};

// Names of the root segments (the subjects), in file order.
std::vector<std::string> VskSubjects(const Vsk& vsk);
// Markers attached directly to `segment`, in file order.
std::vector<VskMarker> VskMarkersOfSegment(const Vsk& vsk, std::string_view segment);
// Markers attached to `subject` (a root segment) or to any segment below it.
std::vector<VskMarker> VskMarkersOfSubject(const Vsk& vsk, std::string_view subject);
// Every subject with its markers (VskMarkersOfSubject of each), in subject
// order, in one pass over the file: use it for all subjects at once.
std::vector<std::pair<std::string, std::vector<VskMarker>>> VskMarkersBySubject(const Vsk& vsk);
// Mean of the positions of the markers attached directly to `segment`, in
// that segment's frame (mm). Error when the segment has no markers.
Expected<Eigen::Vector3d> VskMarkerCentroidMm(const Vsk& vsk, std::string_view segment);

// Reads a .vsk (v3.x or v2.5).
Expected<Vsk> ReadVsk(const std::filesystem::path& path);
// Same, from text in memory; `file_label` names it in messages.
Expected<Vsk> ParseVsk(std::string_view text, const std::string& file_label);

// Writes the Tracker v3.x style: every marker coordinate becomes a parameter
// <Segment>_<Marker>_x|y|z, referenced by name from a
// TargetLocalPointToWorldPoint; one rigid Segment with a JointFree per root
// segment (children nested, joined by a JointFree too); a MarkerSet without
// sticks. Other parameters of `vsk.parameters` are written as well; a name
// that collides with a generated marker parameter is overwritten by the
// marker's position. Numbers are written so they read back exactly.
// Refused (nothing written) when a name is empty or holds whitespace or
// quotes, names repeat, a marker's segment does not exist, a value is not
// finite, or a count or the segment nesting exceeds kVskLimits. Linear in the
// model's size. VERSION is vsk.version when it is a 3.x version, else "3.2" (the
// layout written is 3.x's); MODEL is written when not empty.
Status WriteVsk(const std::filesystem::path& path, const Vsk& vsk);
// The text WriteVsk writes, or the reason it cannot.
Expected<std::string> FormatVsk(const Vsk& vsk);

}  // namespace lifmcr
