// `lifmcr synth`: a synthetic LiFMCR rig with ground truth (replay/synth).
// Parameters: the preset, then the --config YAML on top, then the flags.

#include "apps/commands.h"
#include "apps/frame_list.h"
#include "config/text_escape.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

namespace lifmcr::apps {
namespace {

struct SynthOptions {
  std::string out;
  std::string preset = "small";
  std::string config;
  std::optional<std::string> scene;
  std::optional<std::string> scene_folder;
  std::optional<int> frames;
  std::optional<int> cameras;
  std::optional<std::string> motion;
  std::optional<double> noise;
  std::optional<std::uint64_t> seed;
  bool quiet = false;
  bool no_images = false;
  bool rigid = false;
  std::string render_frames;
};

int RunSynth(const SynthOptions& o) {
  Expected<synth::SynthParams> params = synth::MakePreset(o.preset);
  if (!params) {
    std::cerr << "lifmcr synth: --preset: " << EscapeText(params.error().message) << "\n";
    return 2;
  }
  if (!o.config.empty()) {
    params = synth::LoadSynthConfig(o.config, *params);
    if (!params) {
      std::cerr << "lifmcr synth: " << EscapeText(params.error().message) << "\n";
      return 2;
    }
  }
  if (o.scene) params->rig.scene = *o.scene;
  if (o.scene_folder) params->rig.scene_folder = *o.scene_folder;
  if (o.frames) params->rig.frames = *o.frames;
  if (o.cameras) params->rig.cameras = *o.cameras;
  if (o.motion) params->rig.motion = *o.motion;
  if (o.noise) params->camera.read_noise_dn = *o.noise;
  if (o.seed) params->rig.seed = *o.seed;
  if (o.no_images) params->rig.images = false;
  if (o.rigid) params->rig.rigid = true;
  if (!o.render_frames.empty()) {
    Expected<std::set<std::int64_t>> list = ParseFrameList(o.render_frames, "--render-frames");
    if (!list) {
      std::cerr << "lifmcr synth: " << EscapeText(list.error().message) << "\n";
      return 2;
    }
    for (const std::int64_t f : *list)
      params->rig.render_frames.push_back(static_cast<int>(std::min<std::int64_t>(f, 1 << 30)));
  }
  if (Status s = params->Check(); !s) {
    std::cerr << "lifmcr synth: " << EscapeText(s.error().message) << "\n";
    return 2;
  }
  // Progress: the writer's lines (white images, each frame rendered) and,
  // between them, a heartbeat every 5 s with the time spent, since one r32
  // frame takes a minute or more to render.
  synth::ProgressFn progress;
  std::mutex mutex;
  std::condition_variable wake;
  bool finished = false;
  std::thread heartbeat;
  const auto start = std::chrono::steady_clock::now();
  if (!o.quiet) {
    progress = [&](std::string_view line) {
      std::lock_guard<std::mutex> lock(mutex);
      std::cerr << line << "\n";
    };
    std::cerr << "synth: " << params->rig.cameras << " camera(s) x " << params->rig.frames
              << " frame(s) of " << params->camera.width_px << "x" << params->camera.height_px
              << " (" << params->preset << ") into " << o.out << "\n";
    heartbeat = std::thread([&] {
      std::unique_lock<std::mutex> lock(mutex);
      while (!wake.wait_for(lock, std::chrono::seconds(5), [&] { return finished; }))
        std::cerr
            << "synth: rendering, "
            << static_cast<int>(
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count())
            << " s so far\n";
    });
  }
  Expected<synth::SynthSummary> summary = synth::WriteSyntheticDataset(o.out, *params, progress);
  if (heartbeat.joinable()) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      finished = true;
    }
    wake.notify_all();
    heartbeat.join();
  }
  if (!summary) {
    std::cerr << "lifmcr synth: " << EscapeText(summary.error().message) << "\n";
    return 1;
  }
  std::cout << summary->BriefReport() << "\n";
  return 0;
}

}  // namespace

CommandRun AddSynthCommand(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  app.footer(
      "Writes: into --out, the LiFMCR layout of a synthetic rig rendered with the preset's\n"
      "camera (small 1024x768, medium 3280x2474, r32 6560x4948; an r32 frame takes a minute\n"
      "or more): SCENE/Sequence_00/TypeE_<serial>/ raw BMPs, Vicon/sequence_01.csv,\n"
      "GroundTruth/ (cameras.yaml, poses and marker offsets, virtual depth and depth in mm\n"
      "as float32 TIFF, all-in-focus PNG), and Calibration/ (white images, MLA XML, VSK).\n"
      "Reads: --config YAML when given. Progress on stderr (white images, each frame, and\n"
      "a line every 5 s while rendering) unless --quiet; the summary on stdout.\n"
      "Exit codes: 0 written; 1 a file could not be written; 2 usage or parameter error.");
  app.add_option("--out", o->out, "Dataset root to write (created if needed)")->required();
  app.add_option("--preset", o->preset,
                 "Camera preset: " + std::string(synth::PresetNames()) + " (default small)");
  app.add_option("--config", o->config, "YAML overriding preset fields (camera:, rig:, vicon:)");
  app.add_option("--scene", o->scene,
                 "Scene content: " + std::string(synth::SceneNames()) +
                     " (default table: textured objects, plate, several depths)");
  app.add_option("--scene-folder", o->scene_folder, "Scene folder name (default 00_Synthetic)");
  app.add_option("--frames", o->frames, "Camera triggers per sequence");
  app.add_option("--cameras", o->cameras, "Number of cameras (1..8; 2 = the paper's rig)");
  app.add_option("--motion", o->motion, "Camera motion: smooth|handheld|axis|circle|orbit (orbit: varied angles for calibration)");
  app.add_flag("--rigid", o->rigid,
               "One rigid rig: the cameras move together, c0_from_cx constant (as rig: rigid: "
               "true; default: each camera on its own trajectory)");
  app.add_option("--noise", o->noise, "Sensor read noise sigma in DN");
  app.add_option("--seed", o->seed, "Seed: same seed, same bytes");
  app.add_flag("--quiet", o->quiet, "No progress lines on stderr");
  app.add_flag("--no-images", o->no_images,
               "Poses, Vicon, ground truth and calibration only: no raw frames or depth images");
  app.add_option("--render-frames", o->render_frames,
                 "Render only these triggers' images, e.g. 20-27,5 (poses and ground truth of the "
                 "whole sequence as without it)");
  return [o] { return RunSynth(*o); };
}

}  // namespace lifmcr::apps
