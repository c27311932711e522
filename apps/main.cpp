// `lifmcr`: one executable, one subcommand per job (docs/architecture.md).

#include "apps/commands.h"
#include "apps/logging.h"
#include "config/text_escape.h"

#include <CLI/CLI.hpp>

#include <iostream>
#include <vector>

int main(int argc, char** argv) {
  CLI::App app{
      "lifmcr: rigs of focused plenoptic (MLA) cameras: live recording, replay and\n"
      "processing (virtual depth, totally focused images, point clouds) of LiFMCR-layout\n"
      "datasets, published on LCM. `lifmcr SUBCOMMAND --help` says what each reads, writes\n"
      "and returns."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lifmcr 0.1.0");

  std::string log_level = "warn";
  std::string log_file;
  app.add_option("--log-level", log_level,
                 "Operator log: trace, debug, info (the configuration in force), warn (devices "
                 "lost, drops), error, off")
      ->capture_default_str();
  app.add_option("--log-file", log_file, "Append the log to this file (default: stderr)");

  std::vector<std::pair<CLI::App*, lifmcr::apps::CommandRun>> commands;
  auto add = [&](const char* name, const char* description, auto adder) {
    CLI::App* sub = app.add_subcommand(name, description);
    commands.emplace_back(sub, adder(*sub));
  };
  add("info", "Print what a dataset root, scene, sequence or single file holds",
      lifmcr::apps::AddInfoCommand);
  add("vicon", "Print the poses of one subject of a Vicon CSV export as right-handed CSV",
      lifmcr::apps::AddViconCommand);
  add("synth", "Write a synthetic LiFMCR rig (raw frames, Vicon, calibration) with ground truth",
      lifmcr::apps::AddSynthCommand);
  add("record", "Record a rig live (cameras + Vicon) into the LiFMCR layout",
      lifmcr::apps::AddRecordCommand);
  add("replay", "Play a recorded sequence through the live pipeline onto LCM",
      lifmcr::apps::AddReplayCommand);
  add("monitor", "Terminal view of the pipeline's LCM channels", lifmcr::apps::AddMonitorCommand);
  add("demo", "The whole chain on a synthetic rig: synth -> calibrate -> replay with live registration -> evaluate",
      lifmcr::apps::AddDemoCommand);
  add("grid",
      "Fit the micro-image lattice to a white image (or a textured raw) and write an MLA XML",
      lifmcr::apps::AddGridCommand);
  add("evaluate",
      "Evaluate registered extrinsics against Vicon, with the hand-eye correction: tables, "
      "TUM trajectories, plots",
      lifmcr::apps::AddEvaluateCommand);
  add("depth", "Virtual depth, totally focused image, metric depth and point cloud of one frame",
      lifmcr::apps::AddDepthCommand);
  add("calibrate", "Intrinsic calibration of one camera and its reference map (plenoptic BA), or of a rig's cameras as one (--rig)",
      lifmcr::apps::AddCalibrateCommand);
  add("register", "Register every camera to camera 0's reference map: c0_from_cx per frame",
      lifmcr::apps::AddRegisterCommand);
  add("relate",
      "Relate a rig's cameras held by processes on several hosts: c0_from_cx from their POSE "
      "channels",
      lifmcr::apps::AddRelateCommand);
  add("merge", "Join per-host recordings of one rig into one LiFMCR sequence by trigger index",
      lifmcr::apps::AddMergeCommand);
  add("batch",
      "A whole dataset as resumable units of work for Slurm job arrays or GNU parallel: plan, "
      "run a shard, status, merge",
      lifmcr::apps::AddBatchCommand);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every usage error exits 2, whatever CLI11's own code.
    if (e.get_exit_code() == 0) return app.exit(e);
    // CLI11's own failure message, with the argument it quotes escaped
    // (config/text_escape.h): an argument is text from the user's shell or a script.
    std::cerr << lifmcr::EscapeText(e.what()) << "\nRun with --help for more information.\n";
    return 2;
  }
  if (lifmcr::Status s = lifmcr::apps::ConfigureLogging(log_level, log_file); !s) {
    std::cerr << "lifmcr: " << lifmcr::EscapeText(s.error().message) << "\n";
    return 2;
  }
  for (auto& [sub, run] : commands)
    if (sub->parsed()) return run();
  return 2;
}
