// MergeSequences (sequence_merge.h).

#include "replay/sequence_merge.h"

#include "replay/layout.h"
#include "replay/sequence.h"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <set>
#include <sstream>

namespace lifmcr {

namespace fs = std::filesystem;

namespace {

Expected<std::string> ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path.string() + ": cannot read"};
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return Error{path.string() + ": read error"};
  return bytes;
}

Expected<bool> SameBytes(const fs::path& a, const fs::path& b) {
  std::error_code ec_a, ec_b;
  const auto size_a = fs::file_size(a, ec_a), size_b = fs::file_size(b, ec_b);
  if (ec_a) return Error{a.string() + ": " + ec_a.message()};
  if (ec_b) return Error{b.string() + ": " + ec_b.message()};
  if (size_a != size_b) return false;
  auto bytes_a = ReadBytes(a);
  if (!bytes_a) return bytes_a.error();
  auto bytes_b = ReadBytes(b);
  if (!bytes_b) return bytes_b.error();
  return *bytes_a == *bytes_b;
}

// A Vicon CSV as lines (each with its line ending): the header before the
// first frame line, the frame lines by Vicon frame number, what follows them.
struct ViconLines {
  std::string header;
  std::map<std::int64_t, std::string> frames;
  std::string trailer;
};

// The Vicon frame number a line starts with ("123,0,..."), if it does.
std::optional<std::int64_t> FrameNumberOf(const std::string& line) {
  std::size_t i = 0;
  std::int64_t value = 0;
  while (i < line.size() && line[i] >= '0' && line[i] <= '9' && i < 18)
    value = value * 10 + (line[i++] - '0');
  if (i == 0 || i >= line.size() || line[i] != ',') return std::nullopt;
  return value;
}

Expected<ViconLines> SplitVicon(const fs::path& path) {
  auto bytes = ReadBytes(path);
  if (!bytes) return bytes.error();
  ViconLines lines;
  enum { kHeader, kFrames, kTrailer } part = kHeader;
  std::size_t begin = 0;
  while (begin < bytes->size()) {
    std::size_t end = bytes->find('\n', begin);
    end = end == std::string::npos ? bytes->size() : end + 1;
    const std::string line = bytes->substr(begin, end - begin);
    const std::optional<std::int64_t> frame = FrameNumberOf(line);
    if (part != kTrailer && frame) {
      part = kFrames;
      if (!lines.frames.emplace(*frame, line).second)
        return Error{path.string() + ": Vicon frame " + std::to_string(*frame) + " twice"};
    } else if (part == kHeader) {
      lines.header += line;
    } else {
      part = kTrailer;
      lines.trailer += line;
    }
    begin = end;
  }
  return lines;
}

// One host's Vicon CSVs of one name joined with another's (sequence_merge.h).
Status JoinVicon(ViconLines* into, const fs::path& into_path, const ViconLines& other,
                 const fs::path& other_path) {
  const std::string both = into_path.string() + " and " + other_path.string();
  if (into->header != other.header)
    return Error{both +
                 ": the Vicon CSVs' headers differ (other objects or rate): the hosts "
                 "did not record the same Vicon stream"};
  if (into->trailer != other.trailer)
    return Error{both + ": the Vicon CSVs differ after their frames (another block)"};
  for (const auto& [frame, line] : other.frames) {
    const auto [it, added] = into->frames.emplace(frame, line);
    if (!added && it->second != line)
      return Error{both + ": Vicon frame " + std::to_string(frame) +
                   " differs (the hosts disagree on Vicon)"};
  }
  return Status::Ok();
}

// A file to place in the output: from `source`, or (Vicon joined) `bytes`.
struct Placement {
  fs::path source;  // first host's file
  std::optional<std::string> bytes;
  std::string how;  // Vicon CSVs: how the file was taken
};

Status PlaceOnce(std::map<fs::path, Placement>* plan, const fs::path& target,
                 const fs::path& source) {
  const auto it = plan->find(target);
  if (it == plan->end()) {
    (*plan)[target] = Placement{source, std::nullopt, {}};
    return Status::Ok();
  }
  auto same = SameBytes(it->second.source, source);
  if (!same) return same.error();
  if (!*same)
    return Error{it->second.source.string() + " and " + source.string() +
                 ": two hosts hold this file with different contents"};
  return Status::Ok();
}

}  // namespace

Status SequenceMergeOptions::Check() const {
  if (hosts.empty()) return Error{"merge: hosts: expected at least one sequence folder"};
  if (out.empty()) return Error{"merge: out: empty"};
  for (std::size_t i = 0; i < hosts.size(); ++i)
    for (std::size_t j = i + 1; j < hosts.size(); ++j)
      if (fs::weakly_canonical(hosts[i]) == fs::weakly_canonical(hosts[j]))
        return Error{"merge: " + hosts[j].string() + " is given twice"};
  return Status::Ok();
}

bool SequenceMergeReport::Complete() const {
  return std::all_of(cameras.begin(), cameras.end(),
                     [](const Camera& camera) { return camera.lacking.empty(); });
}

std::string SequenceMergeReport::Describe() const {
  std::ostringstream out;
  out << "triggers: " << triggers << " (" << first_trigger << ".." << last_trigger << ")\n";
  for (const Camera& camera : cameras) {
    out << "camera " << camera.serial << " (from " << camera.host.string() << "): " << camera.frames
        << " frames";
    if (camera.lacking.empty()) {
      out << ", none lacking\n";
      continue;
    }
    out << ", lacks " << camera.lacking.size() << " trigger(s):";
    const std::size_t listed = std::min<std::size_t>(camera.lacking.size(), 20);
    for (std::size_t i = 0; i < listed; ++i) out << " " << camera.lacking[i];
    if (listed < camera.lacking.size()) out << " ...";
    out << "\n";
  }
  for (const std::string& line : vicon) out << line << "\n";
  out << "files: " << linked << " hard-linked, " << copied << " copied, " << joined
      << " Vicon CSV(s) joined\n";
  return out.str();
}

Expected<SequenceMergeReport> MergeSequences(const SequenceMergeOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (fs::exists(options.out) && !(fs::is_directory(options.out) && fs::is_empty(options.out)))
    return Error{options.out.string() +
                 ": exists and is not an empty folder (a merge never overwrites a sequence)"};
  const fs::path out_calibration =
      options.out.parent_path().parent_path() / std::string(layout::kCalibrationFolder);

  SequenceMergeReport report;
  std::map<fs::path, Placement> plan;               // target -> source
  std::map<std::string, fs::path> camera_host;      // serial -> host folder holding it
  std::map<fs::path, std::vector<fs::path>> vicon;  // target -> every host's file
  std::set<std::int64_t> triggers;
  for (const fs::path& host : options.hosts) {
    auto sequence = DiscoverSequence(host);
    if (!sequence) return sequence.error();
    std::set<fs::path> camera_dirs;
    for (const CameraFolder& camera : sequence->cameras) {
      const auto [it, added] = camera_host.emplace(camera.serial, camera.dir);
      if (!added)
        return Error{it->second.string() + " and " + camera.dir.string() + ": camera " +
                     camera.serial + " is held by two hosts"};
      camera_dirs.insert(camera.dir);
      report.cameras.push_back({camera.serial, host, camera.frames.size(), {}});
      triggers.insert(camera.frames.begin(), camera.frames.end());
    }
    for (const fs::path& csv : sequence->vicon_csvs)
      vicon[options.out / std::string(layout::kViconFolder) / csv.filename()].push_back(csv);
    const std::set<fs::path> csvs(sequence->vicon_csvs.begin(), sequence->vicon_csvs.end());
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(host, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      if (!it->is_regular_file()) continue;
      if (csvs.count(it->path())) continue;
      const fs::path relative = fs::relative(it->path(), host);
      if (Status s = PlaceOnce(&plan, options.out / relative, it->path()); !s) return s.error();
    }
    if (ec) return Error{host.string() + ": cannot list: " + ec.message()};
    const std::optional<fs::path> calibration = FindCalibrationFor(host);
    if (calibration && fs::is_directory(*calibration)) {
      for (auto it = fs::recursive_directory_iterator(*calibration, ec);
           !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (!it->is_regular_file()) continue;
        const fs::path target = out_calibration / fs::relative(it->path(), *calibration);
        if (Status s = PlaceOnce(&plan, target, it->path()); !s) return s.error();
      }
      if (ec) return Error{calibration->string() + ": cannot list: " + ec.message()};
    }
  }
  // The Vicon CSVs: once, joined where the hosts' files differ.
  for (const auto& [target, files] : vicon) {
    bool identical = true;
    for (std::size_t i = 1; i < files.size() && identical; ++i) {
      auto same = SameBytes(files.front(), files[i]);
      if (!same) return same.error();
      identical = *same;
    }
    const std::string name = (fs::path(layout::kViconFolder) / target.filename()).string();
    if (identical) {
      plan[target] = Placement{files.front(), std::nullopt,
                               name + ": the same on " + std::to_string(files.size()) + " host(s)"};
      continue;
    }
    auto joined = SplitVicon(files.front());
    if (!joined) return joined.error();
    for (std::size_t i = 1; i < files.size(); ++i) {
      auto other = SplitVicon(files[i]);
      if (!other) return other.error();
      if (Status s = JoinVicon(&*joined, files.front(), *other, files[i]); !s) return s.error();
    }
    std::string bytes = joined->header;
    for (const auto& [frame, line] : joined->frames) bytes += line;
    bytes += joined->trailer;
    plan[target] = Placement{files.front(), std::move(bytes),
                             name + ": joined from " + std::to_string(files.size()) +
                                 " hosts' files by Vicon frame (" +
                                 std::to_string(joined->frames.size()) + " frames)"};
  }
  // A calibration file already in the output root (another sequence merged
  // there before) must be the same.
  for (const auto& [target, placement] : plan) {
    if (!fs::exists(target)) continue;
    if (!target.string().starts_with(out_calibration.string()))
      return Error{target.string() + ": exists (a merge never overwrites a sequence)"};
    auto same = SameBytes(target, placement.source);
    if (!same) return same.error();
    if (!*same)
      return Error{target.string() + " and " + placement.source.string() +
                   ": the output's calibration file differs from the host's"};
  }

  // Triggers each camera lacks.
  if (!triggers.empty()) {
    report.first_trigger = *triggers.begin();
    report.last_trigger = *triggers.rbegin();
  }
  report.triggers = triggers.size();
  std::sort(report.cameras.begin(), report.cameras.end(),
            [](const auto& a, const auto& b) { return a.serial < b.serial; });
  for (SequenceMergeReport::Camera& camera : report.cameras) {
    auto folder = DiscoverCameraFolder(camera_host[camera.serial]);
    if (!folder) return folder.error();
    const std::set<std::int64_t> own(folder->frames.begin(), folder->frames.end());
    for (std::int64_t t : triggers)
      if (!own.count(t)) camera.lacking.push_back(t);
  }

  // Written only now that everything agreed.
  for (const auto& [target, placement] : plan) {
    if (fs::exists(target)) continue;  // an identical calibration file
    std::error_code ec;
    fs::create_directories(target.parent_path(), ec);
    if (ec) return Error{target.parent_path().string() + ": cannot create: " + ec.message()};
    if (placement.bytes) {
      std::ofstream out(target, std::ios::binary);
      out.write(placement.bytes->data(), static_cast<std::streamsize>(placement.bytes->size()));
      out.close();
      if (!out) return Error{target.string() + ": cannot write"};
      ++report.joined;
    } else {
      if (!options.copy) {
        fs::create_hard_link(placement.source, target, ec);
        if (!ec) {
          ++report.linked;
        }
      }
      if (options.copy || ec) {
        ec.clear();
        fs::copy_file(placement.source, target, ec);
        if (ec)
          return Error{target.string() + ": cannot copy " + placement.source.string() + ": " +
                       ec.message()};
        ++report.copied;
      }
    }
    if (!placement.how.empty()) report.vicon.push_back(placement.how);
  }
  return report;
}

}  // namespace lifmcr
