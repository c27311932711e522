// bench_pipeline: a synthetic sequence (default preset medium) replayed through
// the live pipeline as fast as possible with processing on (depth + TF):
// frames per second end to end, processing time per frame, and the latency
// from frame arrival to its messages on LCM (p50, p99); beside it the
// throughput of processing alone (the same frames, one after the other,
// through the same stage) measured in the same run: the ratio is the
// pipeline's overhead (or, above 1, what its concurrency gains).
//   bench_pipeline [--preset small|medium|r32] [--frames N] [--cameras N]
//                  [--concurrency N] [--lcm URL]
// LCM defaults to memq:// (no network); messages are published, not read.

#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/replay_runner.h"
#include "replay/bmp.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

using namespace lifmcr;

int main(int argc, char** argv) {
  std::string preset = "medium", url = "memq://";
  int frames = 6, cameras = 2, concurrency = 2;
  for (int k = 1; k + 1 < argc; k += 2) {
    if (!std::strcmp(argv[k], "--preset"))
      preset = argv[k + 1];
    else if (!std::strcmp(argv[k], "--frames"))
      frames = std::max(1, std::atoi(argv[k + 1]));
    else if (!std::strcmp(argv[k], "--cameras"))
      cameras = std::max(1, std::atoi(argv[k + 1]));
    else if (!std::strcmp(argv[k], "--concurrency"))
      concurrency = std::max(1, std::atoi(argv[k + 1]));
    else if (!std::strcmp(argv[k], "--lcm"))
      url = argv[k + 1];
    else {
      std::fprintf(stderr, "bench_pipeline: unknown option %s\n", argv[k]);
      return 2;
    }
  }
  auto params = synth::MakePreset(preset);
  if (!params) {
    std::fprintf(stderr, "bench_pipeline: %s\n", params.error().message.c_str());
    return 2;
  }
  params->rig.frames = frames;
  params->rig.cameras = cameras;
  char tmpl[] = "/tmp/lifmcr-bench-pipeline-XXXXXX";
  if (!mkdtemp(tmpl)) return 3;
  const std::filesystem::path dir = tmpl;
  std::fprintf(stderr, "bench_pipeline: writing %d x %d frames of preset %s into %s\n", cameras,
               frames, preset.c_str(), tmpl);
  auto summary = synth::WriteSyntheticDataset(dir, *params, {});
  if (!summary) {
    std::fprintf(stderr, "bench_pipeline: %s\n", summary.error().message.c_str());
    return 3;
  }

  apps::ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate.kind = apps::ReplayRate::Kind::kMax;
  options.pipeline.lcm_url = url;
  options.pipeline.max_concurrency = concurrency;
  // Little read-ahead: a frame's arrival is then close to when the pipeline
  // can take it, and the latency measures the pipeline rather than the queue.
  options.pool_buffers = concurrency + 1;
  const auto start = std::chrono::steady_clock::now();
  auto result = apps::RunReplay(options);
  const double pipeline_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!result) {
    std::fprintf(stderr, "bench_pipeline: %s\n", result.error().message.c_str());
    return 3;
  }
  const apps::PipelineReport& r = result->report;

  // Processing alone: the same frames through the same stage, in memory.
  auto layout = DiscoverSequence(summary->sequence_dir);
  std::vector<std::string> serials;
  for (const auto& c : layout->cameras) serials.push_back(c.serial);
  auto processor = apps::DepthProcessor::ForSequence(summary->sequence_dir.string(), serials);
  if (!processor) return 3;
  double alone_s = 0;
  int alone_frames = 0;
  for (const auto& camera : layout->cameras)
    for (std::int64_t f : camera.frames) {
      auto image = ReadBmp(*camera.FramePath(f));
      if (!image) return 3;
      Frame frame;
      frame.serial = camera.serial;
      frame.image = image->View();
      const auto t0 = std::chrono::steady_clock::now();
      auto out = (*processor)->Process(frame);
      alone_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (!out) return 3;
      ++alone_frames;
    }
  const double pipeline_fps = static_cast<double>(r.processed) / pipeline_s;
  const double alone_fps = alone_frames / alone_s;
  std::printf("preset %s, %d cameras x %d frames (%dx%d), concurrency %d, LCM %s\n", preset.c_str(),
              cameras, frames, params->camera.width_px, params->camera.height_px, concurrency,
              url.c_str());
  std::printf(
      "pipeline end to end: %.2f frames/s (%llu processed, %llu skipped, %llu failed, %.2f s)\n",
      pipeline_fps, static_cast<unsigned long long>(r.processed),
      static_cast<unsigned long long>(r.skipped), static_cast<unsigned long long>(r.failed),
      pipeline_s);
  std::printf("sync: %s\n", r.drops.c_str());
  std::printf(
      "stage process (preview + depth + TF + encoding): p50 %.1f ms, p99 %.1f ms per frame\n",
      r.process.p50_ms, r.process.p99_ms);
  std::printf("frame arrival -> depth on LCM: p50 %.1f ms, p99 %.1f ms\n", r.to_publication.p50_ms,
              r.to_publication.p99_ms);
  std::printf("processing alone (same stage, sequential): %.2f frames/s\n", alone_fps);
  std::printf("ratio pipeline / processing alone: %.2f\n", pipeline_fps / alone_fps);
  std::filesystem::remove_all(dir);
  return r.Accounted() && r.failed == 0 && r.sync_lost == 0 ? 0 : 1;
}
