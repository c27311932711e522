#include "replay/synth/synth_writer.h"

#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/synth/cameras_yaml.h"
#include "replay/synth/gt_images.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/trajectory.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "replay/vsk.h"

#include <Eigen/Geometry>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>

namespace lifmcr::synth {
namespace {

constexpr std::array<const char*, 8> kSerials{"40398678", "40398673", "40398674", "40398675",
                                              "40398676", "40398677", "40398679", "40398680"};

std::uint64_t Mix(std::uint64_t a, std::uint64_t b) {
  std::uint64_t x = a * 0x9E3779B97F4A7C15ULL ^ (b + 0x632BE59BD9B4E019ULL);
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

std::string FormatPoseRow(const Pose& pose) {
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d t = pose.translation();
  char row[256];
  std::snprintf(row, sizeof(row), "%.6f,%.6f,%.6f,%.12f,%.12f,%.12f,%.12f", t.x(), t.y(), t.z(),
                q.w(), q.x(), q.y(), q.z());
  return row;
}

Status WriteText(const std::filesystem::path& path, const std::string& text) {
  std::error_code error;
  std::filesystem::create_directories(path.parent_path(), error);
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return MakeErrorAt(path.string(), "/", "cannot write the file");
  return Status::Ok();
}

Status MakeDirs(const std::filesystem::path& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) return MakeErrorAt(dir.string(), "/", "cannot create the folder: " + error.message());
  return Status::Ok();
}

// The first error of parallel work wins; later ones are dropped.
class FirstError {
 public:
  void Set(const Error& error) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!error_) error_ = error;
  }
  bool has() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return error_.has_value();
  }
  const std::optional<Error>& get() const { return error_; }

 private:
  mutable std::mutex mutex_;
  std::optional<Error> error_;
};

Vsk MakeObjectVsk(const std::vector<MarkerCluster>& clusters) {
  Vsk vsk;
  vsk.version = "3.2";
  for (const MarkerCluster& cluster : clusters) {
    vsk.segments.push_back({cluster.subject, ""});
    for (int k = 0; k < 4; ++k) {
      VskMarker marker;
      marker.name = cluster.subject + "_" + std::to_string(k + 1);
      marker.segment = cluster.subject;
      marker.position_mm = cluster.markers_mm[k];
      marker.status = "required";
      marker.radius_mm = 7.0;
      vsk.markers.push_back(marker);
    }
  }
  return vsk;
}

}  // namespace

std::string SynthSummary::BriefReport() const {
  std::ostringstream line;
  line << "synth: " << cameras << " camera(s) x " << frames << " frame(s), " << files
       << " files in " << sequence_dir.string() << " and " << calibration_dir.string() << " ("
       << seconds << " s)";
  return line.str();
}

std::vector<SynthCamera> MakeSynthCameras(const SynthParams& params) {
  std::vector<SynthCamera> cameras;
  for (int k = 0; k < params.rig.cameras; ++k) {
    SynthCamera camera;
    camera.serial = kSerials[k];
    camera.vicon_subject = "cam" + std::to_string(2 * k);
    camera.params = params.camera;
    if (k > 0) {
      // Real units differ: each MLA sits a little differently.
      std::mt19937_64 rng(Mix(params.rig.seed, 100 + k));
      std::uniform_real_distribution<double> unit(-1.0, 1.0);
      const double pitch = camera.params.micro_image_pitch_px;
      camera.params.mla_offset_px +=
          Eigen::Vector2d(0.2 * pitch * unit(rng), 0.2 * pitch * unit(rng));
      camera.params.mla_rotation_rad += 2e-4 * unit(rng);
    }
    camera.cluster = MakeCameraCluster(camera.vicon_subject, Mix(params.rig.seed, 200 + k));
    camera.marker_from_cam = MakeMarkerFromCam(Mix(params.rig.seed, 300 + k));
    cameras.push_back(camera);
  }
  return cameras;
}

std::string FormatPosesCsv(const std::vector<std::int64_t>& frames,
                           const std::vector<std::int64_t>& vicon_frames,
                           const std::vector<Pose>& world_from_cam) {
  std::string text = "frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz\n";
  for (std::size_t k = 0; k < frames.size(); ++k)
    text += std::to_string(frames[k]) + "," + std::to_string(vicon_frames[k]) + "," +
            FormatPoseRow(world_from_cam[k]) + "\n";
  return text;
}

std::string FormatMarkerFromCamCsv(const Pose& marker_from_cam) {
  return "tx_mm,ty_mm,tz_mm,qw,qx,qy,qz\n" + FormatPoseRow(marker_from_cam) + "\n";
}

std::vector<CameraTrajectory> MakeTrajectories(const SynthParams& params, const Scene& scene) {
  const double duration_s = static_cast<double>(params.rig.frames) *
                            params.vicon.trigger_divider / params.vicon.rate_hz;
  std::vector<CameraTrajectory> trajectories;
  for (int k = 0; k < params.rig.cameras; ++k) {
    TrajectoryParams tp;
    tp.motion = params.rig.motion;
    tp.target_mm = scene.Target();
    tp.distance_mm = params.rig.viewing_distance_mm;
    tp.lateral_offset_mm = (k - (params.rig.cameras - 1) / 2.0) * params.rig.baseline_mm;
    tp.duration_s = duration_s;
    tp.amplitude_scale = params.rig.speed_scale;
    tp.seed = Mix(params.rig.seed, 400 + k);
    if (params.rig.rigid) {
      // On the rig: offset along the rig's x, toed in to the look-at point
      // (camera z forward, y down: a turn about y).
      tp.rig_from_cam = Pose::Identity();
      tp.rig_from_cam.translation() = Eigen::Vector3d(tp.lateral_offset_mm, 0, 0);
      tp.rig_from_cam.linear() =
          Eigen::AngleAxisd(-std::atan2(tp.lateral_offset_mm, tp.distance_mm),
                            Eigen::Vector3d::UnitY())
              .toRotationMatrix();
      tp.lateral_offset_mm = 0;
      tp.seed = Mix(params.rig.seed, 400);
      if (k == params.rig.cameras - 1 && params.rig.knock_frame >= 0) {
        // Half a trigger period before the knocked trigger: every sample of
        // it (image and Vicon) sees the new mount.
        tp.knock_time_s =
            TimeOfViconFrame(params.vicon, ViconFrameOfImage(params.vicon, params.rig.knock_frame)) -
            0.5 * params.vicon.trigger_divider / params.vicon.rate_hz;
        tp.knock.translation() = Eigen::Vector3d(params.rig.knock_t_mm, 0, 0);
        tp.knock.linear() =
            Eigen::AngleAxisd(params.rig.knock_r_deg * M_PI / 180.0, Eigen::Vector3d::UnitY())
                .toRotationMatrix();
      }
    }
    trajectories.emplace_back(tp);
  }
  return trajectories;
}

std::vector<std::vector<Pose>> TriggerPoses(const SynthParams& params, const Scene& scene) {
  std::vector<std::vector<Pose>> world_from_cam;
  for (const CameraTrajectory& trajectory : MakeTrajectories(params, scene)) {
    world_from_cam.emplace_back();
    for (int n = 0; n < params.rig.frames; ++n)
      world_from_cam.back().push_back(trajectory.WorldFromCam(
          TimeOfViconFrame(params.vicon, ViconFrameOfImage(params.vicon, n))));
  }
  return world_from_cam;
}

Expected<SynthSummary> WriteSyntheticDataset(const std::filesystem::path& out_dir,
                                             const SynthParams& params,
                                             const ProgressFn& progress) {
  if (Status s = params.Check(); !s) return s.error();
  const auto start = std::chrono::steady_clock::now();
  SynthSummary summary;
  summary.sequence_dir = out_dir / params.rig.scene_folder / params.rig.sequence;
  summary.calibration_dir = out_dir / std::string(layout::kCalibrationFolder);
  summary.cameras = params.rig.cameras;
  summary.frames = params.rig.frames;
  const std::filesystem::path& seq = summary.sequence_dir;
  const std::filesystem::path& calib = summary.calibration_dir;
  std::atomic<std::int64_t> files{0};

  Expected<Scene> made = MakeScene(params.rig.scene, params.rig.seed);
  if (!made) return made.error();
  const Scene& scene = *made;
  const std::vector<SynthCamera> cameras = MakeSynthCameras(params);
  const SynthViconParams& vicon = params.vicon;
  const std::vector<CameraTrajectory> trajectories = MakeTrajectories(params, scene);
  const Pose vicon_from_world = DefaultViconFromWorld();
  Pose world_from_plate_marker;
  const MarkerCluster plate_cluster = MakePlateCluster(
      std::string(kPlateSubject), scene.plate.ViconMarkers(), &world_from_plate_marker);

  for (const auto& dir : {seq, calib}) {
    if (Status s = MakeDirs(dir); !s) return s.error();
  }

  // Calibration folder: the MLA files, white images, the VSK.
  std::vector<PlenopticModel> models;
  for (const SynthCamera& camera : cameras) models.emplace_back(camera.params);
  const Scene white = MakeWhiteScene();
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    const std::filesystem::path xml = layout::MlaXmlPath(calib, cameras[k].serial);
    if (Status s = MakeDirs(xml.parent_path()); !s) return s.error();
    if (Status s = WriteMlaXml(xml, models[k].ToMlaCalibration()); !s) return s.error();
    RenderOptions options;
    options.noise_seed = Mix(params.rig.seed, 500 + k);
    const RawFrame frame = RenderRaw(models[k], white, Pose::Identity(), options);
    const std::filesystem::path bmp = layout::WhiteImagePath(calib, cameras[k].serial, 0);
    if (Status s = MakeDirs(bmp.parent_path()); !s) return s.error();
    if (Status s = WriteBmp(bmp, frame.View()); !s) return s.error();
    files += 2;
    if (progress)
      progress("synth: white image " + std::to_string(k + 1) + "/" +
               std::to_string(cameras.size()) + " rendered (camera " + cameras[k].serial + ")");
  }
  std::vector<MarkerCluster> clusters;
  for (const SynthCamera& camera : cameras) clusters.push_back(camera.cluster);
  clusters.push_back(plate_cluster);
  const std::filesystem::path vsk_path = layout::VskPath(calib);
  if (Status s = MakeDirs(vsk_path.parent_path()); !s) return s.error();
  if (Status s = WriteVsk(vsk_path, MakeObjectVsk(clusters)); !s) return s.error();
  ++files;

  // Vicon: every camera's cluster and the plate at every Vicon frame.
  const std::vector<std::int64_t> vicon_frames = RecordedViconFrames(vicon, params.rig.frames);
  std::vector<std::string> subjects;
  std::vector<std::vector<ViconPoseSample>> samples;
  for (std::size_t k = 0; k <= cameras.size(); ++k) {
    const bool is_plate = k == cameras.size();
    const MarkerCluster& cluster = is_plate ? plate_cluster : cameras[k].cluster;
    subjects.push_back(cluster.subject + ":" + cluster.subject);
    const std::vector<bool> gaps =
        is_plate ? std::vector<bool>(vicon_frames.size(), false)
                 : OcclusionMask(static_cast<int>(vicon_frames.size()), vicon.occlusion_gaps,
                                 vicon.occlusion_gap_frames, Mix(params.rig.seed, 600 + k));
    std::vector<ViconPoseSample> track;
    for (std::size_t f = 0; f < vicon_frames.size(); ++f) {
      ViconPoseSample sample;
      sample.vicon_frame = vicon_frames[f];
      if (!gaps[f]) {
        const Pose truth =
            is_plate ? Pose(vicon_from_world * world_from_plate_marker)
                     : Pose(vicon_from_world *
                            trajectories[k].WorldFromCam(TimeOfViconFrame(vicon, vicon_frames[f])) *
                            cameras[k].marker_from_cam.inverse());
        sample.vicon_from_marker = ObserveCluster(cluster, truth, vicon.marker_noise_mm,
                                                  Mix(params.rig.seed, 700 + k), vicon_frames[f]);
      }
      track.push_back(sample);
    }
    samples.push_back(std::move(track));
  }
  ViconPoseOptions pose_options;
  pose_options.handedness = *ParseHandedness(vicon.handedness);
  pose_options.rotation = *ParseRotationRepresentation(vicon.rotation);
  Expected<ViconBlock> block = MakeObjectsBlock(vicon.rate_hz, subjects, samples, pose_options);
  if (!block) return block.error();
  ViconCsv csv;
  csv.blocks.push_back(std::move(*block));
  csv.crlf = true;  // Tracker runs on Windows
  const std::filesystem::path csv_path = layout::ViconCsvPath(seq, kSequenceCsvIndex);
  csv.path = csv_path.string();
  if (Status s = MakeDirs(csv_path.parent_path()); !s) return s.error();
  if (Status s = WriteViconCsv(csv_path, csv); !s) return s.error();
  ++files;

  // Ground truth: poses at the triggers, marker offsets, cameras.yaml.
  std::vector<std::int64_t> frames, trigger_vicon_frames;
  for (int n = 0; n < params.rig.frames; ++n) {
    frames.push_back(n);
    trigger_vicon_frames.push_back(ViconFrameOfImage(vicon, n));
  }
  const std::vector<std::vector<Pose>> world_from_cam = TriggerPoses(params, scene);
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    if (Status s = WriteText(layout::PosesCsvPath(seq, cameras[k].serial),
                             FormatPosesCsv(frames, trigger_vicon_frames, world_from_cam[k]));
        !s)
      return s.error();
    if (Status s = WriteText(layout::MarkerFromCamCsvPath(seq, cameras[k].serial),
                             FormatMarkerFromCamCsv(cameras[k].marker_from_cam));
        !s)
      return s.error();
    files += 2;
  }
  if (Status s = WriteText(layout::CamerasYamlPath(seq),
                           FormatCamerasYaml(params, cameras, scene.plate, vicon_from_world,
                                             world_from_plate_marker));
      !s)
    return s.error();
  ++files;

  if (!params.rig.images) {
    summary.files = files;
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
  }
  // Before the workers: they write with OpenCV (gt_images.h).
  if (Status s = CheckImageWriters(); !s) return s.error();
  // Frames: parallel over (camera, frame), and over micro-image rows inside.
  for (const SynthCamera& camera : cameras)
    if (Status s = MakeDirs(layout::CameraDir(seq, camera.serial)); !s) return s.error();
  if (Status s = MakeDirs(layout::GroundTruthDir(seq) / std::string(layout::kDepthFolder)); !s)
    return s.error();
  FirstError first_error;
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  std::vector<int> rendered = params.rig.render_frames;
  if (rendered.empty())
    for (int n = 0; n < params.rig.frames; ++n) rendered.push_back(n);
  const int jobs = params.rig.cameras * static_cast<int>(rendered.size());
  tbb::parallel_for(0, jobs, [&](int job) {
    if (first_error.has()) return;
    const auto job_start = std::chrono::steady_clock::now();
    const int k = job % params.rig.cameras;
    const int n = rendered[job / params.rig.cameras];
    const std::string& serial = cameras[k].serial;
    RenderOptions options;
    options.noise_seed = Mix(params.rig.seed, Mix(k, n));
    const RawFrame raw = RenderRaw(models[k], scene, world_from_cam[k][n], options);
    if (Status s = WriteBmp(layout::RawFramePath(seq, serial, n), raw.View()); !s)
      return first_error.Set(s.error());
    if (Status s = WriteFloatTiff(layout::VirtualDepthPath(seq, serial, n), raw.width, raw.height,
                                  raw.virtual_depth);
        !s)
      return first_error.Set(s.error());
    const TfGroundTruth tf = RenderTfGroundTruth(models[k], scene, world_from_cam[k][n]);
    if (Status s =
            WriteFloatTiff(layout::DepthMmPath(seq, serial, n), tf.width, tf.height, tf.depth_mm);
        !s)
      return first_error.Set(s.error());
    if (Status s = WritePng(AllInFocusPath(seq, serial, n), tf.View()); !s)
      return first_error.Set(s.error());
    files += 4;
    const int count = ++done;
    if (progress) {
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - job_start).count();
      char line[160];
      std::snprintf(line, sizeof(line), "synth: %d/%d rendered (camera %s, frame %d, %.2f s)",
                    count, jobs, serial.c_str(), n, seconds);
      std::lock_guard<std::mutex> lock(progress_mutex);
      progress(line);
    }
  });
  if (first_error.get()) return *first_error.get();
  summary.files = files;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

std::filesystem::path AllInFocusPath(const std::filesystem::path& sequence_dir,
                                     std::string_view serial, std::int64_t frame) {
  char name[96];
  std::snprintf(name, sizeof(name), "%.*s_%0*lld_all_in_focus.png", static_cast<int>(serial.size()),
                serial.data(), layout::kFrameDigits, static_cast<long long>(frame));
  return layout::GroundTruthDir(sequence_dir) / "all_in_focus" / name;
}

}  // namespace lifmcr::synth
