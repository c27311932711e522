// `lifmcr vicon FILE.csv`: the poses of one subject of a Vicon CSV export,
// converted to right-handed vicon_from_marker, as CSV on stdout:
//   vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz
// with empty pose fields for frames where the subject was not tracked.

#include "apps/commands.h"
#include "config/frames.h"
#include "config/text_escape.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"

#include <CLI/CLI.hpp>

#include <array>
#include <charconv>
#include <iostream>
#include <memory>
#include <string>

namespace lifmcr::apps {
namespace {

struct ViconArgs {
  std::string file;
  std::string subject;
  std::string rotation = "helical_rad";
  std::string handedness = "left_flip_y";
  bool decimal_comma = false;
  bool short_rows_are_missing = false;
};

// Shortest text that reads back to the same double.
std::string Number(double value) {
  std::array<char, 64> buffer;
  const auto [end, error] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return error == std::errc() ? std::string(buffer.data(), end) : std::string("nan");
}

int RunVicon(const ViconArgs& args) {
  ViconCsvOptions csv_options;
  csv_options.allow_decimal_comma = args.decimal_comma;
  csv_options.short_rows_are_missing = args.short_rows_are_missing;
  auto csv = ReadViconCsv(args.file, csv_options);
  if (!csv.ok()) {
    std::cerr << "lifmcr vicon: " << EscapeText(csv.error().message) << "\n";
    return 1;
  }
  ViconPoseOptions pose_options;
  // Both names were checked by CLI11 against the same lists.
  pose_options.rotation = ParseRotationRepresentation(args.rotation).value();
  pose_options.handedness = ParseHandedness(args.handedness).value();

  std::string subject = args.subject;
  if (subject.empty()) {
    const auto subjects = PoseSubjects(*csv);
    if (subjects.empty()) {
      // No Objects/Segments block: the lookup says what the file has instead.
      auto found = FindSubjectColumns(*csv, "");
      std::cerr << "lifmcr vicon: "
                << EscapeText(found.ok() ? args.file + ": no subject with a pose"
                                         : found.error().message)
                << "\n";
      return 1;
    }
    if (subjects.size() > 1) {
      constexpr std::size_t kListed = 20;
      std::string list;
      for (std::size_t i = 0; i < subjects.size() && i < kListed; ++i)
        list += (list.empty() ? "" : ", ") + Excerpt(subjects[i]);
      if (subjects.size() > kListed) list += ", ...";
      std::cerr << "lifmcr vicon: " << EscapeText(args.file) << ": " << subjects.size()
                << " subjects with poses (" << list << "); choose one with --subject\n";
      return 1;
    }
    subject = subjects.front();
  }
  auto samples = ExtractSubjectPoses(*csv, subject, pose_options);
  if (!samples.ok()) {
    std::cerr << "lifmcr vicon: " << EscapeText(samples.error().message) << "\n";
    return 1;
  }
  std::string out = "vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz\n";
  for (const ViconPoseSample& sample : *samples) {
    out += std::to_string(sample.vicon_frame);
    if (!sample.vicon_from_marker) {
      out += ",,,,,,,\n";
      continue;
    }
    const Pose& pose = *sample.vicon_from_marker;
    Eigen::Quaterniond q(pose.linear());
    q.normalize();
    if (q.w() < 0) q.coeffs() *= -1.0;  // one of the two equal quaternions: qw >= 0
    const Eigen::Vector3d& t = pose.translation();
    for (const double value : {t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z()})
      out += "," + Number(value);
    out += "\n";
  }
  std::cout << out;
  std::cout.flush();
  if (!std::cout) {
    std::cerr << "lifmcr vicon: cannot write to stdout\n";
    return 1;
  }
  return 0;
}

}  // namespace

CommandRun AddViconCommand(CLI::App& app) {
  auto args = std::make_shared<ViconArgs>();
  app.footer(
      "Output: CSV vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz of vicon_from_marker (right-handed,\n"
      "mm, qw >= 0), one row per data row of the Objects (Tracker) or Segments (Nexus) block;\n"
      "frames where the subject is not tracked have empty pose fields.\n"
      "Reads: FILE. Writes: the CSV on stdout; nothing on disk.\n"
      "Exit codes: 0 written; 1 the file could not be read or the subject is not in it\n"
      "(the message on stderr says which); 2 usage error.");
  app.add_option("file", args->file, "Vicon CSV export (Objects or Segments block)")->required();
  app.add_option("--subject", args->subject,
                 "Object or segment: the full 'Subject:Segment' name, or the part before ':' "
                 "when unique. Needed when the file has more than one.");
  app.add_option("--rotation", args->rotation,
                 "How RX,RY,RZ are written: the file does not say. Default helical_rad, "
                 "Tracker's default export (axis * angle in radians); its unit must match the "
                 "file's units row.")
      ->check(CLI::IsMember({"helical_rad", "helical_deg", "euler_xyz_deg", "euler_xyz_rad"}))
      ->capture_default_str();
  app.add_option("--handedness", args->handedness,
                 "Axis mirrored by a left-handed Vicon frame. Default left_flip_y: the LiFMCR "
                 "paper says its Vicon data is left-handed, without saying which axis.")
      ->check(CLI::IsMember({"right", "left_flip_x", "left_flip_y", "left_flip_z"}))
      ->capture_default_str();
  app.add_flag("--decimal-comma", args->decimal_comma,
               "Accept decimal commas ('0,5') in ';'-delimited files (Tracker's Local Numeric "
               "Format)");
  app.add_flag("--short-rows-are-missing", args->short_rows_are_missing,
               "Treat data rows shorter than the header as untracked frames instead of an error");
  return [args] { return RunVicon(*args); };
}

}  // namespace lifmcr::apps
