#pragma once
// The manifest of a plan: one entry per unit that ran to an end, in
// PLAN_DIR/manifest/<unit id>.json, written atomically by the shard that ran
// the unit (batch/atomic_file.h) once the unit's command has exited. One file
// per unit, so shards on different hosts never write the same file and a
// shared file system needs no lock for the manifest. An entry:
//
//   {"unit":"...","state":"done","attempt":1,"exit_code":0,"signal":0,
//    "message":"","log":"logs/<unit id>.log","seconds":1.93,"cpu_seconds":1.88,
//    "peak_rss_kib":181232,
//    "host":"node1","shard":"0/2","finished_utc":"2026-12-06T10:41:07Z",
//    "outputs":[{"path":"units/<unit id>/x.tiff","bytes":123,"xxh64":"0123456789abcdef"}]}
//
// "done": the command exited 0 (or another code of the unit's `done_exits`,
// its last line then kept in `message`) and wrote every file of `writes`;
// `outputs` lists every regular file under the unit's output folder with its
// size and XXH64 (batch/checksum.h). "failed": the command exited non-zero,
// was killed, or left out a file it must write; `message` says which (the
// last line the command printed, or what was missing). A unit without an
// entry is left: never run, or cut off before it ended (killed, preempted,
// the node lost), whatever its output folder holds.

#include "batch/plan.h"
#include "config/error.h"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::batch {

struct OutputFile {
  std::string path;  // relative to PLAN_DIR
  std::uint64_t bytes = 0;
  std::string xxh64;
};

enum class UnitState { kDone, kFailed };
std::string_view ToString(UnitState state);  // "done", "failed"

struct ManifestEntry {
  std::string unit;
  UnitState state = UnitState::kFailed;
  int attempt = 1;      // the how-many-th start of this unit this entry ends (from its log)
  int exit_code = 0;    // the command's exit code; -1 when it was killed by a signal
  int signal = 0;       // the signal that killed it, 0 if none
  std::string message;  // empty when done
  std::string log;      // relative to PLAN_DIR
  double seconds = 0;   // wall time of the command
  // CPU time of the command (user + system, getrusage of the child): what the
  // unit itself cost, whatever else ran on the machine. 0 in entries written
  // before the field existed.
  double cpu_seconds = 0;
  std::int64_t peak_rss_kib = 0;  // the command's peak resident set (getrusage of the child)
  std::string host;
  std::string shard;
  std::string finished_utc;
  std::vector<OutputFile> outputs;

  // "done in 1.93 s, 3 files, 2.1 MB, peak RSS 177 MiB" or
  // "failed (exit 1) after 0.20 s: <message>".
  std::string BriefReport() const;
};

// PLAN_DIR/manifest/<unit>.json and PLAN_DIR/logs/<unit>.log (relative: "logs/<unit>.log").
std::filesystem::path ManifestEntryPath(const std::filesystem::path& plan_dir,
                                        const std::string& unit);
std::string LogPathOf(const std::string& unit);

std::string FormatManifestEntry(const ManifestEntry& entry);
Expected<ManifestEntry> ParseManifestEntry(std::string_view text, const std::string& label);

// Writes the unit's entry atomically.
Status WriteManifestEntry(const std::filesystem::path& plan_dir, const ManifestEntry& entry);
// The unit's entry; nullopt when it has none; an error when it cannot be read
// or parsed (a reader never sees a partial entry, see above, so that means
// someone else wrote the file).
Expected<std::optional<ManifestEntry>> ReadManifestEntry(const std::filesystem::path& plan_dir,
                                                         const std::string& unit);

// Every regular file under the unit's output folder, sorted by path, with size
// and XXH64. An error names the file that could not be read.
Expected<std::vector<OutputFile>> DigestOutputs(const std::filesystem::path& plan_dir,
                                                const Unit& unit);

// Whether a done entry's outputs are still what it records: every file
// present with its size and XXH64, and no other file in the output folder
// (sizes first, so a truncated file costs no hashing). The error names the
// first file that differs and how.
Status VerifyOutputs(const std::filesystem::path& plan_dir, const Unit& unit,
                     const ManifestEntry& entry);

}  // namespace lifmcr::batch
