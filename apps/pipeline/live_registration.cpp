// Live registration set-up (live_registration.h).

#include "apps/pipeline/live_registration.h"

#include "apps/pipeline/camera_setup.h"
#include "evaluation/evaluation_inputs.h"
#include "registration/map/reference_map.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace lifmcr::apps {

namespace fs = std::filesystem;
namespace {

std::string JoinPaths(const std::vector<fs::path>& paths) {
  std::string out;
  for (const fs::path& p : paths) out += (out.empty() ? "" : ", ") + p.string();
  return out;
}

}  // namespace

Status LiveRegistrationOptions::Check() const {
  if (reference_dir.empty()) return Error{"live registration: reference_dir: empty"};
  if (Status s = localizer.Check(); !s) return s;
  if (Status s = monitor.Check(); !s) return s;
  if (!relate && !extrinsics_csv.empty())
    return Error{
        "live registration: --extrinsics-csv: this process holds only some cameras "
        "(--cameras) and relates none; give it to lifmcr relate"};
  if (!relate && rigid_mount)
    return Error{
        "live registration: rigid_mount: this process holds only some cameras "
        "(--cameras) and relates none; give --rigid-mount to lifmcr relate"};
  // intrinsics, fallback_intrinsics, extrinsics_csv: any paths (read or
  // written when loading); rigid_mount: any value where relating.
  return Status::Ok();
}

Expected<std::unique_ptr<ExtrinsicsCsv>> ExtrinsicsCsv::Create(const fs::path& path) {
  std::unique_ptr<ExtrinsicsCsv> csv(new ExtrinsicsCsv());
  csv->path_ = path;
  csv->file_ = std::fopen(path.c_str(), "w");
  if (csv->file_ == nullptr) return Error{path.string() + ": cannot write (--extrinsics-csv)"};
  const std::string header = FormatRegistrationCsv({});
  std::fputs(header.c_str(), csv->file_);
  std::fflush(csv->file_);
  return csv;
}

ExtrinsicsCsv::~ExtrinsicsCsv() {
  if (file_) std::fclose(file_);
}

void ExtrinsicsCsv::Write(const ExtrinsicsRecord& record) {
  RegistrationRow row;
  row.frame = record.trigger_index;
  row.camera = record.serial;
  row.method = record.c0_from_cx.method.empty() ? "pnp" : record.c0_from_cx.method;
  row.c0_from_cx = record.c0_from_cx.transform;
  row.inliers = record.c0_from_cx.inliers;
  row.rmse_px = record.c0_from_cx.rmse_px;
  row.status = record.c0_from_cx.status;
  // FormatRegistrationCsv's text of one row after its header line.
  const std::string text = FormatRegistrationCsv({row});
  const std::string line = text.substr(text.find('\n') + 1);
  std::lock_guard lock(mutex_);
  std::fputs(line.c_str(), file_);
  std::fflush(file_);
  ++rows_;
}

std::uint64_t ExtrinsicsCsv::rows() const {
  std::lock_guard lock(mutex_);
  return rows_;
}

void LiveRegistration::Configure(PipelineOptions* options) const {
  options->registration = stage;
  options->reference_serial = reference_serial;
  options->relate = relate;
  if (csv) {
    std::shared_ptr<ExtrinsicsCsv> writer = csv;
    options->on_extrinsics = [writer](const ExtrinsicsRecord& record) { writer->Write(record); };
  }
}

std::string LiveRegistration::Describe() const {
  std::ostringstream out;
  out << "live registration: camera 0 = " << reference_serial << "; intrinsics from "
      << JoinPaths(intrinsics_files);
  if (csv) out << "; extrinsics CSV " << csv->path().string();
  return out.str();
}

Expected<LiveRegistration> LoadLiveRegistration(const LiveRegistrationOptions& options,
                                                const std::vector<std::string>& serials) {
  if (Status s = options.Check(); !s) return s.error();
  Expected<registration::ReferenceMap> map = registration::ReadReferenceMap(options.reference_dir);
  if (!map) return Error{map.error().message + " (--reference)"};
  LiveRegistration live;
  live.reference_serial = map->camera.serial;
  live.relate = options.relate;
  const bool holds_reference =
      std::find(serials.begin(), serials.end(), live.reference_serial) != serials.end();
  if (options.relate && !holds_reference)
    return Error{options.reference_dir.string() + ": the map's camera " + live.reference_serial +
                 " is not one of the cameras (" + std::to_string(serials.size()) + ")"};
  const fs::path map_intrinsics = options.reference_dir / "intrinsics.yaml";
  const auto add = [&](const fs::path& file) {
    if (std::find(live.intrinsics_files.begin(), live.intrinsics_files.end(), file) ==
        live.intrinsics_files.end())
      live.intrinsics_files.push_back(file);
  };
  if (fs::exists(map_intrinsics)) add(map_intrinsics);
  for (const fs::path& file : options.intrinsics) add(file);
  for (const fs::path& file : options.fallback_intrinsics)
    if (fs::exists(file)) add(file);
  for (const std::string& serial : serials) {
    Expected<std::optional<processing::CameraIntrinsics>> k =
        FindIntrinsics(live.intrinsics_files, serial);
    if (!k) return k.error();
    if (*k) continue;
    if (serial == live.reference_serial)
      return Error{"camera " + serial + " (the map's, camera 0) has no intrinsics in " +
                   (live.intrinsics_files.empty() ? std::string("any file (give --intrinsics)")
                                                  : JoinPaths(live.intrinsics_files))};
    spdlog::warn("live registration: camera {} has no intrinsics (--intrinsics): not localised",
                 serial);
  }
  live.stage = std::make_shared<registration::MapLocalizerStage>(*map, options.localizer);
  if (options.rigid_mount) live.stage->MonitorChanges(options.monitor);
  if (!options.extrinsics_csv.empty()) {
    auto csv = ExtrinsicsCsv::Create(options.extrinsics_csv);
    if (!csv) return csv.error();
    live.csv = std::move(*csv);
  }
  spdlog::info("{}; map {}: {} points", live.Describe(), options.reference_dir.string(),
               map->points.size());
  return live;
}

std::string LiveRegistrationReport(const LiveRegistration& live) {
  const registration::MapLocalizerStage::Counts c = live.stage->counts();
  std::ostringstream out;
  const auto mean_ms = [](double seconds, long long n) {
    return n > 0 ? static_cast<long long>(std::lround(1e3 * seconds / static_cast<double>(n))) : 0;
  };
  out << "registration: " << c.tracked << " frames tracked (" << mean_ms(c.tracked_s, c.tracked)
      << " ms each), " << c.relocalised << " relocalised ("
      << mean_ms(c.relocalised_s, c.relocalised) << " ms), " << c.guided << " re-anchored ("
      << mean_ms(c.guided_s, c.guided) << " ms), " << c.failed << " failed";
  if (c.skipped > 0) out << ", " << c.skipped << " passed through while relocalising";
  out << " (camera 0 = " << live.reference_serial << ")";
  if (c.relocalise_attempts > 0) out << "; " << c.StageReport();
  if (live.csv) out << "; " << live.csv->rows() << " rows in " << live.csv->path().string();
  out << "\n";
  return out.str();
}

}  // namespace lifmcr::apps
