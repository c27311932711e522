#pragma once
// A recorded (or synthetic) sequence played through the pipeline: one
// ReplayCamera per TypeE_<serial>/ folder and the sequence's Vicon CSV
// through ViconCsvSource, driven by the rig's grab loop (RigController, as
// `lifmcr record` drives live cameras), the command's loop polling the
// pipeline. Used by `lifmcr replay`, `lifmcr demo`, the tests and
// bench_pipeline.
//
// Rates: kOriginal plays at the trigger period (10 Hz) and the Vicon rate;
// kFactor at FACTOR times that; both skip frames for processing when it
// cannot keep up (newest wins) and the replay camera loses a frame (an
// underrun, counted) when the pipeline holds all its buffers. kMax delivers
// frames as fast as the pipeline takes them: no skipping, the back-pressure
// reaches the camera's frame pool, every frame is processed; the sources
// stamp host time on the sequence's own clock (ReplayCameraOptions::
// sequence_clock_start_ns), and Vicon frames are released one trigger ahead
// of the slowest camera, in bursts of one trigger's frames
// (RigControllerOptions::vicon_lead_triggers).

#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/live_registration.h"
#include "apps/pipeline/pipeline.h"
#include "config/error.h"

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::apps {

struct ReplayRate {
  enum class Kind { kOriginal, kMax, kFactor } kind = Kind::kOriginal;
  double factor = 1.0;
  // "original", "max" or a number > 0 (1 = original).
  static Expected<ReplayRate> Parse(const std::string& text);
};

struct ReplayRunOptions {
  std::filesystem::path sequence_dir;
  ReplayRate rate;
  bool loop = false;
  bool processing = true;  // false: previews only (no depth, no TF)
  PreviewOptions preview;  // preview and TF image size, depth map size
  // skip_when_busy is the rate's: newest wins when timed, block at max.
  PipelineOptions pipeline;
  // Per replay camera; 0: the frames the pipeline may hold of a camera
  // (PipelineOptions::FramesHeldPerCamera, 12 by default) and the one the
  // camera reads next. A fixed 8 ran out once the lens lane held 4 waiting
  // frames: 3 frames of a timed replay lost for lack of a buffer.
  int pool_buffers = 0;
  // The cameras whose frames are Bayer mosaics: a LiFMCR dataset does not
  // record the pixel format (its BMPs are 8-bit grey), so the user says it
  // (`lifmcr replay --pixel-format`). Serial -> format; the serial "" stands
  // for every camera not named. Bayer cameras are demosaiced for previews and
  // the TF image (colour) and depth runs on luminance, as in `record
  // --publish` (frame_processor.h). A serial not in the sequence is an error.
  PixelFormats pixel_formats;
  // `--cameras SERIAL[,SERIAL...]`: only these cameras of the sequence are
  // opened, processed and published (one host's share of a rig on several
  // hosts); empty: every camera. Trigger indices stay the whole sequence's.
  // With only some cameras, live registration publishes poses (POSE) and
  // relates none: `lifmcr relate` does (PipelineOptions::relate).
  std::string cameras;
  // Intrinsics of the cameras (cameras.yaml schema), searched in order
  // (camera_setup.h, FindIntrinsics): metric depth, and what live
  // registration localises with.
  std::vector<std::filesystem::path> intrinsics;
  // Live registration against a reference map (--reference MAP_DIR); its
  // intrinsics search is MAP_DIR's, then `intrinsics`, then the sequence's
  // GroundTruth/cameras.yaml. nullopt: frames pass through.
  std::optional<LiveRegistrationOptions> registration;
  // Called about once a second on the command's thread.
  std::function<void(const PipelineReport&)> on_status;
  const std::atomic<bool>* stop = nullptr;  // set by a signal handler; may be null
  Status Check() const;  // every field; the message names the field
};

struct ReplayRunResult {
  PipelineReport report;
  int cameras = 0;
  std::uint64_t frames_in_sequence = 0;  // frame files, per pass, all cameras
  std::uint64_t camera_underruns = 0;    // frames the replay cameras lost (timed replay)
  std::uint64_t camera_failed = 0;       // unreadable frame files
  int passes = 0;
  std::string registration;  // LiveRegistrationReport, with --reference
  std::string FinalReport() const;
};

// `--pixel-format` values: "FORMAT" (every camera) or "SERIAL=FORMAT", each
// FORMAT one of config/rig_config.h's camera pixel formats (Mono8, BGR8,
// BayerRG8, BayerGR8, BayerGB8, BayerBG8). Errors quote the value.
Expected<PixelFormats> ParsePixelFormatOptions(const std::vector<std::string>& values);

// `processor` replaces the stage the options ask for (tests: a slowed stage).
Expected<ReplayRunResult> RunReplay(const ReplayRunOptions& options,
                                    std::unique_ptr<FrameProcessor> processor = nullptr);

}  // namespace lifmcr::apps
