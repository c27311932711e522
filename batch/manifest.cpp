#include "batch/manifest.h"

#include "batch/atomic_file.h"
#include "batch/checksum.h"
#include "config/text_escape.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <map>

namespace lifmcr::batch {

namespace fs = std::filesystem;
using nlohmann::json;

std::string_view ToString(UnitState state) { return state == UnitState::kDone ? "done" : "failed"; }

std::string ManifestEntry::BriefReport() const {
  char text[160];
  if (state == UnitState::kDone) {
    std::uint64_t bytes = 0;
    for (const OutputFile& f : outputs) bytes += f.bytes;
    std::snprintf(text, sizeof text, "done in %.2f s, %zu file%s, %.1f MB, peak RSS %lld MiB",
                  seconds, outputs.size(), outputs.size() == 1 ? "" : "s", bytes / 1e6,
                  static_cast<long long>(peak_rss_kib / 1024));
    return text;
  }
  std::string why = signal != 0 ? "killed by signal " + std::to_string(signal)
                                : "exit " + std::to_string(exit_code);
  std::snprintf(text, sizeof text, " after %.2f s: ", seconds);
  return "failed (" + why + ")" + text + message;
}

fs::path ManifestEntryPath(const fs::path& plan_dir, const std::string& unit) {
  return plan_dir / "manifest" / (unit + ".json");
}

std::string LogPathOf(const std::string& unit) { return "logs/" + unit + ".log"; }

std::string FormatManifestEntry(const ManifestEntry& e) {
  json outputs = json::array();
  for (const OutputFile& f : e.outputs)
    outputs.push_back({{"path", f.path}, {"bytes", f.bytes}, {"xxh64", f.xxh64}});
  const json j = {{"unit", e.unit},
                  {"state", ToString(e.state)},
                  {"attempt", e.attempt},
                  {"exit_code", e.exit_code},
                  {"signal", e.signal},
                  {"message", e.message},
                  {"log", e.log},
                  {"seconds", e.seconds},
                  {"cpu_seconds", e.cpu_seconds},
                  {"peak_rss_kib", e.peak_rss_kib},
                  {"host", e.host},
                  {"shard", e.shard},
                  {"finished_utc", e.finished_utc},
                  {"outputs", outputs}};
  return j.dump(1) + "\n";
}

Expected<ManifestEntry> ParseManifestEntry(std::string_view text, const std::string& label) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    return Error{label + ": expected a JSON manifest entry: " + e.what()};
  }
  ManifestEntry e;
  try {
    e.unit = j.at("unit").get<std::string>();
    const std::string state = j.at("state").get<std::string>();
    if (state == "done")
      e.state = UnitState::kDone;
    else if (state == "failed")
      e.state = UnitState::kFailed;
    else
      return Error{label + ": \"state\": expected done or failed, got '" + Excerpt(state) + "'"};
    e.attempt = j.at("attempt").get<int>();
    e.exit_code = j.at("exit_code").get<int>();
    e.signal = j.at("signal").get<int>();
    e.message = j.at("message").get<std::string>();
    e.log = j.at("log").get<std::string>();
    e.seconds = j.at("seconds").get<double>();
    e.cpu_seconds = j.value("cpu_seconds", 0.0);  // absent in entries of earlier versions
    e.peak_rss_kib = j.at("peak_rss_kib").get<std::int64_t>();
    e.host = j.at("host").get<std::string>();
    e.shard = j.at("shard").get<std::string>();
    e.finished_utc = j.at("finished_utc").get<std::string>();
    for (const json& f : j.at("outputs"))
      e.outputs.push_back({f.at("path").get<std::string>(), f.at("bytes").get<std::uint64_t>(),
                           f.at("xxh64").get<std::string>()});
  } catch (const json::exception& ex) {
    return Error{label + ": expected a manifest entry (docs/batch.md): " + ex.what()};
  }
  return e;
}

Status WriteManifestEntry(const fs::path& plan_dir, const ManifestEntry& entry) {
  return WriteFileAtomically(ManifestEntryPath(plan_dir, entry.unit), FormatManifestEntry(entry));
}

Expected<std::optional<ManifestEntry>> ReadManifestEntry(const fs::path& plan_dir,
                                                         const std::string& unit) {
  const fs::path path = ManifestEntryPath(plan_dir, unit);
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(path, ec))) return std::optional<ManifestEntry>();
  Expected<std::string> text = ReadWholeFile(path);
  if (!text) return text.error();
  Expected<ManifestEntry> entry = ParseManifestEntry(*text, path.string());
  if (!entry) return entry.error();
  if (entry->unit != unit)
    return Error{path.string() + ": \"unit\": expected '" + unit + "', got '" +
                 Excerpt(entry->unit) + "'"};
  return std::optional<ManifestEntry>(std::move(*entry));
}

namespace {

// Regular files under the unit's folder, relative to PLAN_DIR, sorted; other
// kinds of entries (links, FIFOs) are errors: a unit's outputs are plain files.
Expected<std::vector<std::string>> ListOutputs(const fs::path& plan_dir, const Unit& unit) {
  std::vector<std::string> files;
  const fs::path root = plan_dir / unit.outputs;
  std::error_code ec;
  if (!fs::exists(root, ec)) return files;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::file_status st = it->symlink_status(ec);
    if (ec) break;
    if (fs::is_directory(st)) continue;
    const std::string rel = fs::relative(it->path(), plan_dir, ec).generic_string();
    if (!fs::is_regular_file(st)) return Error{it->path().string() + ": not a regular file"};
    files.push_back(rel);
  }
  if (ec) return Error{root.string() + ": cannot list: " + ec.message()};
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

Expected<std::vector<OutputFile>> DigestOutputs(const fs::path& plan_dir, const Unit& unit) {
  Expected<std::vector<std::string>> files = ListOutputs(plan_dir, unit);
  if (!files) return files.error();
  std::vector<OutputFile> out;
  for (const std::string& rel : *files) {
    Expected<FileDigest> d = DigestFile(plan_dir / rel);
    if (!d) return d.error();
    out.push_back({rel, d->bytes, d->xxh64});
  }
  return out;
}

Status VerifyOutputs(const fs::path& plan_dir, const Unit& unit, const ManifestEntry& entry) {
  Expected<std::vector<std::string>> files = ListOutputs(plan_dir, unit);
  if (!files) return files.error();
  std::map<std::string, const OutputFile*> recorded;
  for (const OutputFile& f : entry.outputs) recorded[f.path] = &f;
  for (const std::string& rel : *files)
    if (!recorded.count(rel)) return Error{rel + ": not in the manifest entry (written later?)"};
  for (const OutputFile& f : entry.outputs) {
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(plan_dir / f.path, ec);
    if (ec) return Error{f.path + ": missing (" + ec.message() + ")"};
    if (size != f.bytes)
      return Error{f.path + ": " + std::to_string(size) + " bytes, the manifest records " +
                   std::to_string(f.bytes)};
  }
  for (const OutputFile& f : entry.outputs) {
    Expected<FileDigest> d = DigestFile(plan_dir / f.path);
    if (!d) return d.error();
    if (d->xxh64 != f.xxh64)
      return Error{f.path + ": XXH64 " + d->xxh64 + ", the manifest records " + f.xxh64};
  }
  return Status::Ok();
}

}  // namespace lifmcr::batch
