#include "apps/commands.h"
#include "apps/info_report.h"
#include "config/text_escape.h"

#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>

namespace lifmcr::apps {

CommandRun AddInfoCommand(CLI::App& app) {
  struct Args {
    std::string path;
    bool json = false;
    bool quick = false;
  };
  auto args = std::make_shared<Args>();
  app.footer(
      "PATH is a LiFMCR dataset root (scenes and Calibration/), a scene,\n"
      "a sequence (Vicon/ and TypeE_<serial>/ folders), a camera folder, a Calibration folder,\n"
      "or one file: a raw frame (.bmp), an MLA calibration (.xml, RayCalibData 1.0), a Vicon\n"
      "CSV export (.csv), a Vicon model (.vsk) or a rig file (.yaml).\n"
      "For cameras: frame count, first/last frame, missing frames, image size and pixel format\n"
      "(every frame header is checked against its file size), and the camera's MLA calibration.\n"
      "Exit code: 0 when everything read cleanly, 1 when a problem was found (all are listed),\n"
      "2 on a usage error.");
  app.add_option("path", args->path, "Dataset root, scene, sequence, folder or file")->required();
  app.add_flag("--json", args->json, "Print the same report as JSON");
  app.add_flag("--quick", args->quick, "Check only the first and last frame header of each camera");
  return [args] {
    InfoOptions options;
    options.check_every_frame = !args->quick;
    auto report = DescribePath(args->path, options);
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
