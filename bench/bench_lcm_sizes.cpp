// bench_lcm_sizes: the size of every LCM message the pipeline publishes per
// camera frame (preview, depth, TF image), at each synthetic preset, as
// encoded (lcm getEncodedSize), against the receive buffer a stock Linux
// receiver has (net.core.rmem_default, 212992 bytes on Debian): a message
// larger than about half of it is lost whenever the receiver is a little
// late. Also the depth map as 16-bit PNG beside the published 8-bit one, as
// the baseline of this run.
//   bench_lcm_sizes [--presets small,medium,r32]

#include "bench/bench_usage.h"
#include "apps/pipeline/frame_processor.h"
#include "replay/bmp.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <sstream>
#include <string>
#include <unistd.h>

using namespace lifmcr;

namespace {

int PreviewBytes(const apps::EncodedImage& image) {
  lifmcr_lcm::preview_image_t m;
  m.serial = "40398678";
  m.size = static_cast<int32_t>(image.bytes.size());
  m.data = image.bytes;
  return m.getEncodedSize();
}

int DepthBytes(const std::vector<std::uint8_t>& png) {
  lifmcr_lcm::depth_image_t m;
  m.serial = "40398678";
  m.size = static_cast<int32_t>(png.size());
  m.data = png;
  return m.getEncodedSize();
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_lcm_sizes [--presets small,medium,r32]\n"
    "The encoded size of every LCM message the pipeline publishes per camera frame (preview,\n"
    "depth, TF image) at each preset, against a stock receiver's buffer (212992 bytes).\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string presets = "small,medium,r32";
  for (int i = 1; i + 1 < argc; ++i)
    if (std::strcmp(argv[i], "--presets") == 0) presets = argv[++i];
  const double stock = 212992;
  std::printf("%-7s %11s %9s %9s %9s %12s %9s\n", "preset", "raw", "preview", "depth", "tf",
              "depth 16-bit", "largest");
  std::stringstream list(presets);
  std::string preset;
  while (std::getline(list, preset, ',')) {
    auto params = synth::MakePreset(preset);
    if (!params) {
      std::fprintf(stderr, "%s\n", params.error().message.c_str());
      return 2;
    }
    params->rig.frames = 1;
    params->rig.cameras = 1;
    const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                      ("lifmcr_bench_lcm_sizes_" + std::to_string(getpid()));
    auto summary = synth::WriteSyntheticDataset(dir / preset, *params);
    if (!summary) {
      std::fprintf(stderr, "%s\n", summary.error().message.c_str());
      return 1;
    }
    auto layout = DiscoverSequence(summary->sequence_dir);
    const auto& camera = layout->cameras.at(0);
    auto processor =
        apps::DepthProcessor::ForSequence(summary->sequence_dir.string(), {camera.serial});
    auto image = ReadBmp(*camera.FramePath(camera.frames.at(0)));
    if (!processor || !image) return 1;
    Frame frame;
    frame.serial = camera.serial;
    frame.image = image->View();
    auto out = (*processor)->Process(frame);
    if (!out || !out->depth || !out->preview || !out->tf) return 1;
    auto sixteen = apps::EncodeDepth(out->depth->values, out->depth->width, out->depth->height, 16);
    const int preview = PreviewBytes(*out->preview), depth = DepthBytes(out->depth->png),
              tf = PreviewBytes(*out->tf), depth16 = DepthBytes(sixteen->png);
    const int largest = std::max({preview, depth, tf});
    char raw[32];
    std::snprintf(raw, sizeof raw, "%dx%d", image->width, image->height);
    std::printf(
        "%-7s %11s %9d %9d %9d %12d %9d  largest / stock rmem_default %.2f; depth 8/16-bit %.2f\n",
        preset.c_str(), raw, preview, depth, tf, depth16, largest, largest / stock,
        static_cast<double>(depth) / depth16);
    std::filesystem::remove_all(dir);
  }
  return 0;
}
