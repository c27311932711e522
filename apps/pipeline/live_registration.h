#pragma once
// Live registration for `lifmcr replay SEQ --reference MAP_DIR` and
// `lifmcr record --publish --reference MAP_DIR`: the reference map, the
// intrinsics every camera's processing chain gets, the per-camera localizer
// (registration/live/map_localizer.h) as the pipeline's registration stage, and
// the optional --extrinsics-csv file.
//
// MAP_DIR: the folder `lifmcr calibrate --out` writes (reference map and
// intrinsics.yaml of camera 0) or the one `lifmcr register
// --reference-from-ground-truth` writes (OUT/reference, no intrinsics). The
// map's camera is camera 0 of every c0_from_cx.
//
// Intrinsics of a camera: the first file that lists its serial, in this
// order: MAP_DIR/intrinsics.yaml (when present), the --intrinsics files,
// then the command's fallbacks (replay: SEQ/GroundTruth/cameras.yaml when
// present). Camera 0 must have intrinsics; another camera without any is
// processed but not localised (a warning names it).
//
// --extrinsics-csv FILE: every published c0_from_cx as a row of the
// registration.csv of `lifmcr register` (evaluation/evaluation_inputs.h:
// frame = the trigger index, method = the estimator, status `ok` or why it
// failed), written as it is published (flushed per row), so `lifmcr
// evaluate --registration FILE` reads it, also after Ctrl-C.

#include "apps/pipeline/pipeline.h"
#include "config/error.h"
#include "registration/live/extrinsics_monitor.h"
#include "registration/live/map_localizer.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace lifmcr::apps {

struct LiveRegistrationOptions {
  std::filesystem::path reference_dir;               // MAP_DIR
  std::vector<std::filesystem::path> intrinsics;     // --intrinsics, in order
  std::vector<std::filesystem::path> fallback_intrinsics;  // searched last (the command's)
  std::filesystem::path extrinsics_csv;              // empty: none
  registration::LocalizerOptions localizer;
  // Change detection of c0_from_cx (the rig file's registration.rigid_mount).
  bool rigid_mount = false;
  registration::ExtrinsicsMonitorOptions monitor;
  // The process holds every camera and relates their poses itself. false
  // (`--cameras` naming only some of the rig's): poses go out on POSE for
  // `lifmcr relate`; the map's camera need not be held here, and
  // extrinsics_csv and rigid_mount, which belong to the relating process,
  // are errors.
  bool relate = true;
  Status Check() const;  // every field; the message names the field
};

// Writes ExtrinsicsRecords as registration.csv rows (thread-safe).
class ExtrinsicsCsv {
 public:
  static Expected<std::unique_ptr<ExtrinsicsCsv>> Create(const std::filesystem::path& path);
  ~ExtrinsicsCsv();
  ExtrinsicsCsv(const ExtrinsicsCsv&) = delete;
  ExtrinsicsCsv& operator=(const ExtrinsicsCsv&) = delete;
  void Write(const ExtrinsicsRecord& record);
  std::uint64_t rows() const;
  const std::filesystem::path& path() const { return path_; }

 private:
  ExtrinsicsCsv() = default;
  std::filesystem::path path_;
  std::FILE* file_ = nullptr;
  mutable std::mutex mutex_;
  std::uint64_t rows_ = 0;
};

struct LiveRegistration {
  std::shared_ptr<registration::MapLocalizerStage> stage;
  std::string reference_serial;  // the map's camera: camera 0
  // The intrinsics search order for the processing chain (camera_setup.h).
  std::vector<std::filesystem::path> intrinsics_files;
  std::shared_ptr<ExtrinsicsCsv> csv;  // null without --extrinsics-csv
  bool relate = true;                  // LiveRegistrationOptions::relate
  // Sets the pipeline's registration stage, reference camera and CSV observer.
  void Configure(PipelineOptions* options) const;
  // "map MAP_DIR: camera 40398678, 2113 points; intrinsics from A, B".
  std::string Describe() const;
};

// Reads the map, checks that camera 0 is one of `serials` (when relating) with intrinsics,
// warns about the other cameras without intrinsics, opens the CSV.
Expected<LiveRegistration> LoadLiveRegistration(const LiveRegistrationOptions& options,
                                                const std::vector<std::string>& serials);

// The rows a run wrote, for the command's final report:
// "extrinsics: 16 published (camera 40398673: 8 ok, 8 tracked), CSV FILE".
std::string LiveRegistrationReport(const LiveRegistration& live);

}  // namespace lifmcr::apps
