#include "replay/vicon_poses.h"

#include "config/text_escape.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>
#include <unordered_set>

namespace lifmcr {
namespace {

constexpr std::array<std::string_view, 3> kRotationNames = {"RX", "RY", "RZ"};
constexpr std::array<std::string_view, 3> kTranslationNames = {"TX", "TY", "TZ"};

bool IsDegrees(RotationRepresentation representation) {
  return representation == RotationRepresentation::kHelicalDeg ||
         representation == RotationRepresentation::kEulerXyzDeg;
}

// Names (user text: each escaped and shortened), or descriptions (not).
std::string Join(const std::vector<std::string>& names, size_t max_count = 12,
                 bool are_names = true) {
  std::string joined;
  for (size_t i = 0; i < names.size() && i < max_count; ++i) {
    if (i > 0) joined += ", ";
    joined += are_names ? Excerpt(names[i]) : names[i];
  }
  if (names.size() > max_count) joined += ", ... (" + std::to_string(names.size()) + " in all)";
  return joined;
}

// Objects blocks first (Tracker), then Segments (Nexus), each in file order.
std::vector<const ViconBlock*> PoseBlocks(const ViconCsv& csv) {
  std::vector<const ViconBlock*> blocks;
  for (const char* name : {"Objects", "Segments"})
    for (const ViconBlock& block : csv.blocks)
      if (block.name == name) blocks.push_back(&block);
  return blocks;
}

// Why a file without pose blocks cannot give poses, saying what it holds.
Error NoPoseBlockError(const ViconCsv& csv) {
  std::string what = "no Objects/Segments block, so no poses (rotations) to extract; it has ";
  std::vector<std::string> described;
  for (const ViconBlock& block : csv.blocks) {
    if (block.name == "Trajectories") {
      described.push_back("Trajectories with " + std::to_string(block.Entities().size()) +
                          " markers (" + Join(block.Entities(), 6) + ") of subjects " +
                          Join(block.subjects));
    } else {
      described.push_back(block.name);
    }
  }
  what += Join(described, 12, false);
  return MakeError(csv.path, 0, 0, what);
}

Expected<ViconSubjectColumns> ColumnsOf(const ViconCsv& csv, const ViconBlock& block,
                                        const std::string& full_name) {
  ViconSubjectColumns columns;
  columns.block = &block;
  columns.full_name = full_name;
  for (size_t i = 0; i < 3; ++i) {
    const auto rotation = block.FindColumn(full_name, kRotationNames[i]);
    const auto translation = block.FindColumn(full_name, kTranslationNames[i]);
    if (!rotation || !translation) {
      return MakeError(csv.path, block.first_line + 3, 0,
                       "'" + full_name + "' in block " + block.name + " has no " +
                           std::string(!rotation ? kRotationNames[i] : kTranslationNames[i]) +
                           " column: expected RX, RY, RZ, TX, TY, TZ");
    }
    columns.rotation[i] = *rotation;
    columns.translation[i] = *translation;
  }
  return columns;
}

}  // namespace

std::vector<std::string> PoseSubjects(const ViconCsv& csv) {
  std::vector<std::string> subjects;
  std::unordered_set<std::string> seen;
  for (const ViconBlock* block : PoseBlocks(csv))
    for (const std::string& entity : block->Entities())
      if (seen.insert(entity).second) subjects.push_back(entity);
  return subjects;
}

Expected<ViconSubjectColumns> FindSubjectColumns(const ViconCsv& csv, std::string_view subject) {
  const std::vector<const ViconBlock*> blocks = PoseBlocks(csv);
  if (blocks.empty()) return NoPoseBlockError(csv);
  for (const ViconBlock* block : blocks) {
    // The prefix of each entity, from its last column (one pass, not one per entity).
    std::unordered_map<std::string_view, std::string_view> prefix_of;
    for (const ViconColumn& column : block->columns) prefix_of[column.subject] = column.prefix;
    for (const std::string& entity : block->Entities()) {
      const std::string_view prefix = prefix_of[entity];
      if (entity == subject || std::string(prefix) + entity == subject)
        return ColumnsOf(csv, *block, entity);
    }
  }
  for (const ViconBlock* block : blocks) {
    std::vector<std::string> matches;
    for (const std::string& entity : block->Entities())
      if (SubjectOf(entity) == subject) matches.push_back(entity);
    if (matches.size() == 1) return ColumnsOf(csv, *block, matches.front());
    if (matches.size() > 1) {
      return MakeError(csv.path, block->first_line + 2, 0,
                       "subject '" + Excerpt(subject) + "' is ambiguous in block " +
                           block->name + ": it matches " + Join(matches) +
                           "; give the full Subject:Segment name");
    }
  }
  return MakeError(
      csv.path, blocks.front()->first_line + 2, 0,
      "no subject '" + Excerpt(subject) +
          "' in the Objects/Segments blocks; subjects there: " + Join(PoseSubjects(csv), 50));
}

Expected<std::vector<ViconPoseSample>> ExtractSubjectPoses(const ViconCsv& csv,
                                                           std::string_view subject,
                                                           const ViconPoseOptions& options) {
  auto found = FindSubjectColumns(csv, subject);
  if (!found.ok()) return found.error();
  const ViconSubjectColumns& columns = *found;
  const ViconBlock& block = *columns.block;
  const std::string expected_unit = IsDegrees(options.rotation) ? "deg" : "rad";
  for (size_t i = 0; i < 3; ++i) {
    const ViconColumn& column = block.columns[columns.rotation[i]];
    if (column.unit != expected_unit) {
      return MakeError(csv.path, block.first_line > 0 ? block.first_line + 4 : 0, 0,
                       "field " + std::to_string(columns.rotation[i] + 3) + " (" +
                           columns.full_name + " " + column.name + "): the units row says '" +
                           column.unit + "' but the rotation representation " +
                           std::string(ToString(options.rotation)) + " is in " +
                           (expected_unit == "deg" ? "degrees" : "radians") +
                           "; choose a representation in '" + column.unit + "'");
    }
  }
  std::vector<ViconPoseSample> samples;
  samples.reserve(block.num_rows());
  for (size_t row = 0; row < block.num_rows(); ++row) {
    ViconPoseSample sample;
    sample.vicon_frame = block.frames[row];
    Eigen::Vector3d r;
    Eigen::Vector3d t;
    int present = 0;
    for (size_t i = 0; i < 3; ++i) {
      r[i] = block.at(row, columns.rotation[i]);
      t[i] = block.at(row, columns.translation[i]);
      present += !std::isnan(r[i]);
      present += !std::isnan(t[i]);
    }
    if (present == 0) {
      samples.push_back(sample);
      continue;
    }
    if (present != 6) {
      return MakeError(csv.path, block.LineOf(row), block.ColumnOf(row, columns.rotation[0]),
                       "frame " + std::to_string(sample.vicon_frame) + ", " + columns.full_name +
                           ": partial RX..TZ tuple; expected all six values or none");
    }
    auto pose = ViconToRightHanded(options.handedness, RotationFromVicon(options.rotation, r), t);
    if (!pose.ok()) {
      return MakeError(csv.path, block.LineOf(row), block.ColumnOf(row, columns.rotation[0]),
                       "frame " + std::to_string(sample.vicon_frame) + ", " + columns.full_name +
                           " (" + std::string(ToString(options.rotation)) +
                           "): " + pose.error().message);
    }
    sample.vicon_from_marker = *pose;
    samples.push_back(sample);
  }
  return samples;
}

Expected<ViconBlock> MakeObjectsBlock(int rate_hz, const std::vector<std::string>& subjects,
                                      const std::vector<std::vector<ViconPoseSample>>& samples,
                                      const ViconPoseOptions& options) {
  const std::string where = "Objects block";
  if (rate_hz <= 0) {
    return MakeErrorAt("<memory>", where, "rate must be > 0 Hz, got " + std::to_string(rate_hz));
  }
  if (subjects.size() != samples.size()) {
    return MakeErrorAt("<memory>", where,
                       std::to_string(subjects.size()) + " subjects but " +
                           std::to_string(samples.size()) + " sample lists");
  }
  ViconBlock block;
  block.name = "Objects";
  block.rate_hz = rate_hz;
  const std::string rotation_unit = IsDegrees(options.rotation) ? "deg" : "rad";
  for (const std::string& subject : subjects) {
    if (subject.empty() || std::count(subjects.begin(), subjects.end(), subject) != 1) {
      return MakeErrorAt("<memory>", where,
                         "subject names must be non-empty and distinct, got '" + subject + "'");
    }
    for (const std::string_view name : kRotationNames)
      block.columns.push_back(ViconColumn{subject, "", std::string(name), rotation_unit});
    for (const std::string_view name : kTranslationNames)
      block.columns.push_back(ViconColumn{subject, "", std::string(name), "mm"});
    const std::string subject_name(SubjectOf(subject));
    if (std::find(block.subjects.begin(), block.subjects.end(), subject_name) ==
        block.subjects.end())
      block.subjects.push_back(subject_name);
  }
  std::map<int64_t, size_t> row_of_frame;
  for (const auto& list : samples)
    for (const ViconPoseSample& sample : list) row_of_frame[sample.vicon_frame] = 0;
  for (auto& [frame, row] : row_of_frame) {
    row = block.frames.size();
    block.frames.push_back(frame);
    block.sub_frames.push_back(0);
  }
  block.values.assign(block.frames.size() * block.columns.size(),
                      std::numeric_limits<double>::quiet_NaN());
  for (size_t s = 0; s < subjects.size(); ++s) {
    std::vector<bool> written(block.frames.size(), false);
    for (const ViconPoseSample& sample : samples[s]) {
      const size_t row = row_of_frame.at(sample.vicon_frame);
      if (written[row]) {
        return MakeErrorAt("<memory>", where,
                           "subject '" + subjects[s] + "' has frame " +
                               std::to_string(sample.vicon_frame) + " twice");
      }
      written[row] = true;
      if (!sample.vicon_from_marker) continue;
      Eigen::Matrix3d rotation;
      Eigen::Vector3d translation_mm;
      RightHandedToVicon(options.handedness, *sample.vicon_from_marker, &rotation, &translation_mm);
      const Eigen::Vector3d r = RotationToVicon(options.rotation, rotation);
      if (!r.allFinite() || !translation_mm.allFinite()) {
        return MakeErrorAt("<memory>", where,
                           "subject '" + subjects[s] + "' frame " +
                               std::to_string(sample.vicon_frame) + ": the pose is not finite");
      }
      double* values = &block.values[row * block.columns.size() + s * 6];
      for (int i = 0; i < 3; ++i) {
        values[i] = r[i];
        values[3 + i] = translation_mm[i];
      }
    }
  }
  return block;
}

}  // namespace lifmcr
