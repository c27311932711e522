#include "apps/commands.h"
#include "apps/info_gentl.h"
#include "apps/info_report.h"
#include "config/text_escape.h"

#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>
#include <unistd.h>

namespace lifmcr::apps {

CommandRun AddInfoCommand(CLI::App& app) {
  struct Args {
    std::string path;
    bool json = false;
    bool quick = false;
    std::string gentl;
  };
  auto args = std::make_shared<Args>();
  app.footer(
      "PATH is a LiFMCR dataset root (scenes and Calibration/), a scene,\n"
      "a sequence (Vicon/ and TypeE_<serial>/ folders), a camera folder, a Calibration folder,\n"
      "or one file: a raw frame (.bmp), an MLA calibration (.xml, RayCalibData 1.0), a Vicon\n"
      "CSV export (.csv), a Vicon model (.vsk) or a rig file (.yaml).\n"
      "For cameras: frame count, first/last frame, missing frames, image size and pixel format\n"
      "(every frame header is checked against its file size), and the camera's MLA calibration.\n"
      "--gentl PRODUCER.cti lists what a GenTL producer (a frame grabber's .cti) exposes:\n"
      "its interfaces and devices with their ids and serials, the values a rig file's\n"
      "driver: {kind: gentl, cti: ..., interface: ..., device: ...} takes.\n"
      "Progress: on a terminal, a line on stderr while the frames of a camera are checked.\n"
      "Reads: PATH (and the MLA files a sequence's Calibration/ holds), or the producer.\n"
      "Writes: the report on stdout (text, or JSON with --json); nothing on disk.\n"
      "Exit codes: 0 when everything read cleanly, 1 when a problem was found (all are\n"
      "listed), 2 on a usage error.");
  app.add_option("path", args->path, "Dataset root, scene, sequence, folder or file");
  app.add_option("--gentl", args->gentl, "List the interfaces and devices of a GenTL producer (.cti)");
  app.add_flag("--json", args->json, "Print the same report as JSON");
  app.add_flag("--quick", args->quick, "Check only the first and last frame header of each camera");
  return [args] {
    if (!args->gentl.empty()) {
      const nlohmann::json gentl = DescribeGenTlProducer(args->gentl);
      if (args->json)
        std::cout << gentl.dump(2) << "\n";
      else
        std::cout << FormatGenTlText(gentl, "");
      return gentl["problems"].empty() ? 0 : 1;
    }
    if (args->path.empty()) {
      std::cerr << "lifmcr info: give a PATH (or --gentl PRODUCER.cti)\n";
      return 2;
    }
    InfoOptions options;
    options.check_every_frame = !args->quick;
    // Progress on a terminal only: a line on stderr redrawn in place.
    const bool terminal = isatty(STDERR_FILENO) == 1;
    if (terminal)
      options.progress = [](const std::string& serial, std::size_t done, std::size_t total) {
        std::cerr << "\rinfo: camera " << serial << ": checked " << done << " of " << total
                  << " frame headers\x1b[K" << std::flush;
      };
    auto report = DescribePath(args->path, options);
    if (terminal) std::cerr << "\r\x1b[K" << std::flush;
    if (!report.ok()) {
      std::cerr << "lifmcr info: " << EscapeText(report.error().message) << "\n";
      return 1;
    }
    if (args->json)
      std::cout << report->dump(2) << "\n";
    else
      std::cout << FormatInfoText(*report);
    return (*report)["problems"].empty() ? 0 : 1;
  };
}

}  // namespace lifmcr::apps
