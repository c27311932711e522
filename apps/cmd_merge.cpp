// `lifmcr merge HOSTDIR... --out SEQ`: per-host recordings of one rig into
// one LiFMCR sequence (replay/sequence_merge.h).

#include "apps/commands.h"
#include "config/text_escape.h"
#include "replay/sequence_merge.h"

#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr::apps {
namespace {

struct MergeArgs {
  std::vector<std::string> hosts;
  std::string out;
  bool copy = false;
};

int RunMerge(const MergeArgs& args) {
  SequenceMergeOptions options;
  for (const std::string& host : args.hosts) options.hosts.emplace_back(host);
  options.out = args.out;
  options.copy = args.copy;
  auto report = MergeSequences(options);
  if (!report) {
    std::cerr << "lifmcr merge: " << EscapeText(report.error().message) << "\n";
    return 3;
  }
  std::cout << "sequence: " << args.out << "\n" << report->Describe();
  return report->Complete() ? 0 : 1;
}

}  // namespace

CommandRun AddMergeCommand(CLI::App& app) {
  auto args = std::make_shared<MergeArgs>();
  app.footer(
      "Joins the recordings of one rig made on several hosts (each host's `lifmcr record\n"
      "--cameras ...` sequence folder, SCENE/SEQ, holding its cameras) into the sequence\n"
      "--out (OUT_ROOT/SCENE/SEQ, which must not exist or be empty) by trigger index: every\n"
      "camera folder as it is, the Vicon CSV once, the Calibration/ folders beside the\n"
      "scenes into OUT_ROOT/Calibration/. Files are hard-linked where the file system allows,\n"
      "else copied (--copy: always copied). Reports per camera the triggers it lacks (some\n"
      "other camera has them).\n"
      "Errors (nothing written): a camera held by two hosts (both folders named); Vicon CSVs\n"
      "whose headers differ or that disagree on a Vicon frame (both files named; files that\n"
      "only start or end at other frames are joined frame by frame); any other file two\n"
      "hosts hold with different bytes.\n"
      "Reads: the HOSTDIR sequence folders and the Calibration/ folders beside their scenes.\n"
      "Writes: --out (and OUT_ROOT/Calibration/): links or copies of those files, the joined\n"
      "Vicon CSV where the hosts' files differ.\n"
      "Exit codes: 0 merged, every camera has every trigger; 1 merged, a camera lacks a\n"
      "trigger; 2 usage; 3 nothing merged (the error says why).");
  app.add_option("HOSTDIR", args->hosts, "Per-host sequence folders (SCENE/SEQ)")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--out", args->out, "The merged sequence folder (OUT_ROOT/SCENE/SEQ)")->required();
  app.add_flag("--copy", args->copy, "Copy the files instead of hard-linking them");
  return [args] { return RunMerge(*args); };
}

}  // namespace lifmcr::apps
