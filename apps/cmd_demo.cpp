// `lifmcr demo`: the embedded default: a small synthetic rig written to a
// temporary folder (or --out) and replayed through the pipeline on LCM.

#include "apps/commands.h"
#include "config/text_escape.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <CLI/CLI.hpp>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <vector>

#include <unistd.h>

namespace lifmcr::apps {

namespace {

struct Args {
  std::string out;
  int frames = 10;
  int cameras = 2;
  std::string rate = "max";
  std::string lcm_url;
  bool no_processing = false;
  bool loop = false;
};

int RunDemo(const Args& args) {
  std::filesystem::path out = args.out;
  if (out.empty()) {
    std::string pattern = (std::filesystem::temp_directory_path() / "lifmcr-demo-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) {
      std::cerr << "lifmcr demo: cannot create a temporary folder in "
                << std::filesystem::temp_directory_path().string() << "\n";
      return 3;
    }
    out = pattern;
  }
  auto params = synth::MakePreset("small");
  if (!params) {
    std::cerr << "lifmcr demo: " << EscapeText(params.error().message) << "\n";
    return 2;
  }
  params->rig.frames = args.frames;
  params->rig.cameras = args.cameras;
  if (Status s = params->Check(); !s) {
    std::cerr << "lifmcr demo: " << EscapeText(s.error().message) << "\n";
    return 2;
  }
  std::cerr << "lifmcr demo: writing a synthetic rig (" << args.cameras << " cameras, "
            << args.frames << " frames, preset small) into " << out.string() << "\n";
  auto summary = synth::WriteSyntheticDataset(out, *params, {});
  if (!summary) {
    std::cerr << "lifmcr demo: " << EscapeText(summary.error().message) << "\n";
    return 3;
  }
  std::cerr << summary->BriefReport() << "\n"
            << "lifmcr demo: replaying " << summary->sequence_dir.string()
            << " on LCM; watch it with `scripts/lcm-spy.sh` or `build/apps/lifmcr monitor` in "
               "another terminal (add --loop to keep it playing)\n";
  const int code = RunReplayCommand(summary->sequence_dir.string(), args.rate, args.loop,
                                    args.lcm_url, !args.no_processing, 2, "lifmcr demo", {});
  std::cout << "sequence: " << summary->sequence_dir.string() << "\n"
            << "watch: scripts/lcm-spy.sh (channels LIFMCR_*), or build/apps/lifmcr monitor; "
               "record: lcm-logger -c 'LIFMCR_.*' demo.lcmlog\n";
  return code;
}

}  // namespace

CommandRun AddDemoCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.footer(
      "Writes a small synthetic rig (lifmcr synth --preset small) into a temporary folder\n"
      "(or --out) and replays it through the live pipeline on LCM (lifmcr replay), then\n"
      "prints the summary and how to watch it in lcm-spy.\n"
      "Reads: nothing. Writes: the synthetic rig (a new temporary folder, or --out) and the\n"
      "LCM channels of lifmcr replay.\n"
      "Exit codes: 0 every frame accounted for and none failed; 1 a processing failure;\n"
      "2 usage error; 3 the rig could not be written or LCM opened.");
  app.add_option("--out", args->out, "Dataset root to write (default: a new temporary folder)");
  app.add_option("--frames", args->frames, "Triggers to render")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  app.add_option("--cameras", args->cameras, "Cameras")
      ->check(CLI::Range(1, 8))
      ->capture_default_str();
  app.add_option("--rate", args->rate, "original | max | FACTOR")->capture_default_str();
  app.add_option("--lcm", args->lcm_url, "LCM URL");
  app.add_flag("--no-processing", args->no_processing, "Previews only");
  app.add_flag("--loop", args->loop, "Replay until Ctrl-C");
  return [args] { return RunDemo(*args); };
}

}  // namespace lifmcr::apps
