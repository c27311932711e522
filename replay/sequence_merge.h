#pragma once
// Joins the recordings of one rig made on several hosts (each host records
// its own cameras: `lifmcr record --cameras ...`) into one LiFMCR sequence
// (`lifmcr merge HOSTDIR... --out SEQ`; docs/recording.md, "Several hosts").
//
// By trigger index: a frame file's number is its trigger's on every host
// (the hosts share the hardware trigger), so the camera folders are joined
// as they are and every camera's frames keep their names. A trigger some
// camera has and another lacks is reported per camera.
//
// Files are hard-linked into the output where the file system allows
// (recordings are never modified, and a link costs no space or time), else
// copied; the report counts both. Either way the output's bytes are the
// inputs'.
//   TypeE_<serial>/   from the one host that holds the camera; two hosts
//                     holding one camera is an error naming both folders
//   Vicon/*.csv       once: byte-identical files are taken as they are;
//                     files that differ are joined line by line by Vicon
//                     frame number when their headers agree and each frame
//                     both hold is the same line (hosts that started or
//                     stopped at other times); else an error naming both
//                     files and the first frame they disagree on
//   anything else     (GroundTruth/ of a synthetic sequence, and the
//                     Calibration/ folder beside the scene: MLA files per
//                     camera, white images, the VSK): taken once; a file
//                     two hosts hold with other bytes is an error naming both
// Everything is checked before the first file is written; the output
// sequence folder must not exist or be empty (as `lifmcr record`'s).

#include "config/error.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr {

struct SequenceMergeOptions {
  std::vector<std::filesystem::path> hosts;  // sequence folders (SCENE/SEQ), at least one
  std::filesystem::path out;                 // the sequence folder to write (OUT_ROOT/SCENE/SEQ)
  bool copy = false;                         // copy every file (no hard links)
  Status Check() const;
};

struct SequenceMergeReport {
  struct Camera {
    std::string serial;
    std::filesystem::path host;  // the host sequence folder it came from
    std::size_t frames = 0;
    std::vector<std::int64_t> lacking;  // triggers some camera has and this one lacks
  };
  std::vector<Camera> cameras;  // by serial
  std::size_t triggers = 0;     // triggers any camera has
  std::int64_t first_trigger = 0, last_trigger = -1;
  std::uint64_t linked = 0, copied = 0,
                joined = 0;        // files; joined: Vicon CSVs written line by line
  std::vector<std::string> vicon;  // one line per Vicon CSV: how it was taken
  bool Complete() const;           // no camera lacks a trigger
  // Several lines: per camera its frames and the triggers it lacks (the
  // first 20 listed), the Vicon CSVs, files linked and copied.
  std::string Describe() const;
};

Expected<SequenceMergeReport> MergeSequences(const SequenceMergeOptions& options);

}  // namespace lifmcr
