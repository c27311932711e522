#pragma once
// Poses of Vicon objects and segments from a parsed CSV export, and the
// inverse used by writers (the synthetic rig generator, the recorder).
//
// A row of an Objects (Tracker) or Segments (Nexus) block gives, per object,
// RX RY RZ (a rotation in the representation the rig file names: the file
// does not say) and TX TY TZ in mm, both in Vicon's frame. With
//   R_vicon = RotationFromVicon(representation, (RX, RY, RZ)),
//   t_vicon = (TX, TY, TZ),
// the pose is ViconToRightHanded(handedness, R_vicon, t_vicon) (config/frames.h):
//   vicon_from_marker = [S R_vicon S | S t_vicon],  S = ReflectionOf(handedness),
// mapping marker (object) coordinates into the right-handed Vicon frame, mm.

#include "config/error.h"
#include "config/frames.h"
#include "replay/vicon_csv.h"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr {

struct ViconPoseOptions {
  // How RX, RY, RZ are written. Tracker's default export is helical in rad.
  RotationRepresentation rotation = RotationRepresentation::kHelicalRad;
  // The paper: LiFMCR's Vicon data is left-handed. Which axis is mirrored is
  // not stated; y is the default until the reference plate pins it down.
  Handedness handedness = Handedness::kLeftFlipY;
};

struct ViconPoseSample {
  int64_t vicon_frame = 0;
  std::optional<Pose> vicon_from_marker;  // right-handed, mm; empty when untracked
};

// The block that holds `subject` (a pointer into the ViconCsv searched, valid
// while it lives) and the columns of its pose.
struct ViconSubjectColumns {
  const ViconBlock* block = nullptr;
  std::string full_name;                // "cam0:cam0" as in the file
  std::array<size_t, 3> rotation{};     // RX, RY, RZ column indices
  std::array<size_t, 3> translation{};  // TX, TY, TZ column indices
};

// Finds `subject` in the Objects block, else the Segments block, matching the
// full "Subject:Segment" name or the part before ':' when that is unique.
// Errors: no Objects/Segments block (saying what the file has instead), an
// unknown subject (listing the ones there), an ambiguous one.
Expected<ViconSubjectColumns> FindSubjectColumns(const ViconCsv& csv, std::string_view subject);

// Full names of every object/segment with a pose, from the Objects and
// Segments blocks, in file order.
std::vector<std::string> PoseSubjects(const ViconCsv& csv);

// One sample per data row of the block holding `subject` (rows with sub
// frames > 0 give samples with the same vicon_frame). Errors (naming the
// file, line and column): the units row disagrees with the representation
// (deg vs rad), or a row's rotation is not a rotation after conversion.
Expected<std::vector<ViconPoseSample>> ExtractSubjectPoses(const ViconCsv& csv,
                                                           std::string_view subject,
                                                           const ViconPoseOptions& options = {});

// A Tracker-style Objects block: for each subject (written as given, e.g.
// "cam0:cam0") the columns RX,RY,RZ,TX,TY,TZ with units rad or deg (from the
// representation) and mm. Rows are the sorted union of the frames of every
// subject's samples, sub frame 0; a subject without a sample at a frame, or
// with an empty pose, gets empty cells. Poses are converted back with
// RightHandedToVicon and RotationToVicon, so ExtractSubjectPoses on the
// written file returns them. Errors: subjects and samples of different
// sizes, an empty or repeated subject name, a frame twice for one subject.
Expected<ViconBlock> MakeObjectsBlock(int rate_hz, const std::vector<std::string>& subjects,
                                      const std::vector<std::vector<ViconPoseSample>>& samples,
                                      const ViconPoseOptions& options = {});

}  // namespace lifmcr
