// Recording throughput: two in-memory cameras at full R32 size (6560x4948,
// one 8-bit, one 24-bit: 32.5 and 97.4 MB frames) free-running as fast as
// the recorder takes them (a camera waits for a free pooled buffer, so the
// disk sets the pace), through the real grab threads, recorder queues and
// O_DIRECT writer, into a folder on the machine's disk. Printed beside the
// disk's own sequential O_DIRECT write bandwidth measured in the same run
// with `dd if=/dev/zero bs=32M oflag=direct`, as a ratio. dd runs just
// before and just after the recorder and their mean is the baseline, so a
// disk shared with other work biases neither side.
//
// The data written is bounded (default 3 GB for the recorder, 2 x 1 GiB for dd)
// and deleted afterwards. 1 MB = 1e6 bytes.
//
// GenTL mode (--gentl PRODUCER.cti, the test producer
// build/tests/lifmcr_gentl_sim.cti): the same two R32-sized cameras are
// GenTlCameras served by the producer, which writes every frame into the
// pool buffers the driver announced (as a grabber's DMA would; the
// simulator writes each frame's first row and chunk, or with --fill-all every
// row with memset, whose CPU is then in the figure). By default the producer
// makes a frame whenever a buffer is queued (flow control, as the in-memory
// cameras wait for a free buffer), so the disk sets the pace and the ratio is
// the GenTL path's sustained throughput against dd. A CoaXPress camera cannot
// wait: with --load F both cameras instead free-run at one rate, chosen to
// offer F of the slower of two dd runs before, and any frame the recorder
// cannot keep up with is a counted drop (a producer underrun, a frame id
// gap, a recorder drop): the figure says whether that load is sustained with
// nothing lost.
//
// Usage: bench_record [folder on the disk under test (default /var/tmp)]
//                     [recorder GB (default 3)] [writer threads (default 1)]
//                     [--gentl PRODUCER.cti [--load FRACTION] [--fill-all]]

#include "acquisition/memory_camera.h"
#include "acquisition/recorder.h"
#include "drivers/gentl_camera.h"
#include "acquisition/rig_controller.h"
#include "config/rig_config.h"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;
using namespace lifmcr;

constexpr int kR32Width = 6560;
constexpr int kR32Height = 4948;

// dd's own figure in MB/s (it prints "..., 1.1 GB/s" or "..., 950 MB/s").
double DdDirectWriteMbPerS(const fs::path& dir) {
  const fs::path file = dir / "dd_direct.bin";
  const std::string command =
      "dd if=/dev/zero of='" + file.string() + "' bs=32M count=32 oflag=direct conv=fsync 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return 0;
  char line[512];
  std::string last;
  while (std::fgets(line, sizeof(line), pipe) != nullptr) last = line;
  ::pclose(pipe);
  fs::remove(file);
  // "2147483648 bytes (2.1 GB, 2.0 GiB) copied, 1.9 s, 1.1 GB/s"
  const auto comma = last.rfind(", ");
  const auto bytes_end = last.find(" bytes");
  const auto copied = last.find("copied, ");
  if (comma == std::string::npos || bytes_end == std::string::npos || copied == std::string::npos)
    return 0;
  const double bytes = std::atof(last.substr(0, bytes_end).c_str());
  const double seconds = std::atof(last.substr(copied + 8).c_str());
  return seconds > 0 ? bytes / seconds / 1e6 : 0;
}


// User + system CPU seconds of this process so far.
double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return t.tv_sec + t.tv_usec * 1e-6; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> positional;
  std::string gentl_cti;
  double gentl_load = 0.0;  // 0: flow control
  bool gentl_fill_all = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--gentl" && i + 1 < argc) {
      gentl_cti = argv[++i];
    } else if (arg == "--fill-all") {
      gentl_fill_all = true;
    } else if (arg == "--load" && i + 1 < argc) {
      gentl_load = std::atof(argv[++i]);
    } else if (arg == "-h" || arg == "--help") {
      std::printf(
          "usage: bench_record [DIR (/var/tmp)] [GB (3)] [WRITER_THREADS (1)]\n"
          "                    [--gentl PRODUCER.cti [--load F] [--fill-all]]\n"
          "Two in-memory R32-sized cameras through the grab threads and the recorder into\n"
          "DIR; prints sustained MB/s against dd oflag=direct in the same folder, drops and\n"
          "CPU cores. bench/README.md says what each mode measures.\n");
      return 0;
    } else if (!arg.empty() && arg[0] == '-') {
      // An option we do not know would otherwise become the output folder.
      std::fprintf(stderr, "bench_record: unknown option '%s' (see --help)\n", arg.c_str());
      return 2;
    } else {
      positional.push_back(arg);
    }
  }
  const fs::path base = positional.size() > 0 ? fs::path(positional[0]) : fs::path("/var/tmp");
  const double budget_gb = positional.size() > 1 ? std::atof(positional[1].c_str()) : 3.0;
  const int writer_threads = positional.size() > 2 ? std::atoi(positional[2].c_str()) : 1;
  const bool gentl = !gentl_cti.empty();
  if (gentl && !(gentl_load >= 0.0 && gentl_load <= 2.0)) {
    std::fprintf(stderr, "bench_record: --load must be in [0, 2] (0: flow control)\n");
    return 2;
  }
  const fs::path dir = base / ("lifmcr_bench_record_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const double dd_before_mb_s = DdDirectWriteMbPerS(dir);

  RigConfig rig;
  rig.name = "bench";
  for (int i = 0; i < 2; ++i) {
    CameraConfig camera;
    camera.serial = i == 0 ? "R32MONO" : "R32BGR";
    camera.name = "cam" + std::to_string(i);
    if (gentl) {
      camera.driver.kind = DriverKind::kGenTl;
      camera.driver.cti = gentl_cti;
      camera.trigger.mode = TriggerMode::kFreeRun;
      camera.pixel_format = i == 0 ? CameraPixelFormat::kMono8 : CameraPixelFormat::kBgr8;
      camera.exposure_us = 1000.0;
    }
    rig.cameras.push_back(camera);
  }
  // Offered load of the free-running GenTL cameras: `gentl_load` of dd's figure.
  const double trigger_bytes = static_cast<double>(kR32Width) * kR32Height * (1 + 3);
  // The disk's figure swings between runs (here 0.9-1.7 GB/s): the rate
  // follows the slower of two dd runs, so the cameras offer what the disk
  // sustains rather than a lucky burst.
  const bool fixed_rate = gentl && gentl_load > 0.0;
  const double dd_for_rate_mb_s =
      fixed_rate ? std::min(dd_before_mb_s, DdDirectWriteMbPerS(dir)) : dd_before_mb_s;
  // Flow control: free-run asked at a rate the disk never reaches, so
  // queued buffers, not ticks, pace the producer.
  const double gentl_rate_hz =
      fixed_rate ? gentl_load * dd_for_rate_mb_s * 1e6 / trigger_bytes : 100.0;
  if (gentl) {
    // The test producer's cameras: these serials, R32 sensors.
    ::setenv("LIFMCR_GENTL_SIM_DEVICES", "R32MONO,R32BGR", 1);
    ::setenv("LIFMCR_GENTL_SIM_SENSOR",
             (std::to_string(kR32Width) + "x" + std::to_string(kR32Height)).c_str(), 1);
    // Like a grabber's DMA, the producer costs no host CPU (--fill-all: it
    // writes every row with memset, which then competes for the CPU).
    if (!gentl_fill_all) ::setenv("LIFMCR_GENTL_SIM_FILL", "first_row", 1);
    if (!fixed_rate) ::setenv("LIFMCR_GENTL_SIM_FLOW_CONTROL", "1", 1);
  }
  RecorderOptions options;
  options.root_dir = dir;
  options.queue_frames = gentl ? 6 : 4;
  options.writer_threads = writer_threads;
  options.direct_io = true;
  auto recorder = Recorder::Create(rig, options);
  if (!recorder) {
    std::fprintf(stderr, "bench_record: %s\n", recorder.error().message.c_str());
    return 1;
  }
  std::vector<std::unique_ptr<Camera>> cameras;
  for (int i = 0; gentl && i < 2; ++i) {
    GenTlCameraOptions camera;
    camera.camera_index = i;
    // Fixed rate: the recorder's queue, one being written, one in the grab
    // thread, the rest queued in the producer for the next frames. Flow
    // control: no more buffers than queue slots, as for the in-memory
    // cameras, so a full pool, not a full queue, holds the producer back.
    camera.pool_buffers = fixed_rate ? options.queue_frames + 4 : options.queue_frames;
    camera.free_run_rate_hz = gentl_rate_hz;
    cameras.push_back(std::make_unique<GenTlCamera>(rig.cameras[i], camera));  // opened by Start
  }
  for (int i = 0; !gentl && i < 2; ++i) {
    MemoryCameraOptions camera;
    camera.serial = rig.cameras[i].serial;
    camera.width = kR32Width;
    camera.height = kR32Height;
    camera.format = i == 0 ? PixelFormat::kMono8 : PixelFormat::kBgr8;
    // No more buffers than queue slots: a full pool, not a full queue, stops the
    // camera, so nothing is dropped and the disk sets the pace.
    camera.pool_frames = options.queue_frames;
    camera.free_run = true;
    camera.wait_for_buffer = true;
    cameras.push_back(std::make_unique<MemoryCamera>(camera));
  }
  RigControllerOptions controller_options;
  // Frames placed on the cameras' own rate (the GenTL cameras free-run at it).
  if (gentl) controller_options.trigger_hz = gentl_rate_hz;
  RigController controller(std::move(cameras), {false, false}, nullptr, recorder->get(),
                           controller_options);
  if (Status s = controller.Start(); !s) {
    std::fprintf(stderr, "bench_record: %s\n", s.error().message.c_str());
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start_s = ProcessCpuSeconds();
  const double budget_bytes = budget_gb * 1e9;
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const RecorderStats stats = (*recorder)->Stats();
    std::uint64_t bytes = 0;
    for (const auto& c : stats.cameras) bytes += c.bytes_written;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (static_cast<double>(bytes) >= budget_bytes || elapsed > 60 || stats.stop_reason) break;
  }
  controller.Stop();
  (*recorder)->Stop();
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cores_used = (ProcessCpuSeconds() - cpu_start_s) / elapsed_s;
  const RigHealth health = controller.Health();
  std::uint64_t bytes = 0, frames = 0, drops = 0, underruns = 0;
  for (const CameraHealth& c : health.cameras) {
    bytes += c.recorder.bytes_written;
    frames += c.recorder.written;
    drops += c.Lost();
    underruns += c.driver.underruns;
  }
  fs::remove_all(dir);
  fs::create_directories(dir);
  const double dd_after_mb_s = DdDirectWriteMbPerS(dir);
  const double dd_mb_s = (dd_before_mb_s + dd_after_mb_s) / 2;
  fs::remove_all(dir);

  const double recorder_mb_s = static_cast<double>(bytes) / 1e6 / elapsed_s;
  std::printf(
      "bench_record: 2 cameras 6560x4948 (Mono8 32.5 MB + BGR8 97.4 MB frames), "
      "%d writer thread(s), into %s\n",
      writer_threads, base.string().c_str());
  const char* fill_text =
      gentl_fill_all ? "every row (memset)" : "the first row and the chunk (DMA-like)";
  if (fixed_rate)
    std::printf(
        "  GenTL: producer %s, both cameras free-running at %.2f Hz = %.0f MB/s offered "
        "(%.2f of dd before, slower of two runs: %.0f MB/s), producer writes %s\n",
        gentl_cti.c_str(), gentl_rate_hz, gentl_rate_hz * trigger_bytes / 1e6, gentl_load,
        dd_for_rate_mb_s, fill_text);
  else if (gentl)
    std::printf(
        "  GenTL: producer %s, a frame whenever a buffer is queued (the disk sets the pace), "
        "producer writes %s\n",
        gentl_cti.c_str(), fill_text);
  for (const CameraHealth& c : health.cameras)
    std::printf("  %-8s %llu frames, %.0f MB, lost %llu\n", c.serial.c_str(),
                static_cast<unsigned long long>(c.recorder.written),
                static_cast<double>(c.recorder.bytes_written) / 1e6,
                static_cast<unsigned long long>(c.Lost()));
  std::printf(
      "  recorder: %llu frames, %.0f MB in %.2f s = %.0f MB/s sustained; drops %llu, "
      "underruns %llu; %s\n",
      static_cast<unsigned long long>(frames), static_cast<double>(bytes) / 1e6, elapsed_s,
      recorder_mb_s, static_cast<unsigned long long>(drops),
      static_cast<unsigned long long>(underruns), health.recorder.OneLine().c_str());
  std::printf(
      "  dd oflag=direct bs=32M (1.07 GB, same folder, same run): %.0f MB/s before, "
      "%.0f MB/s after, mean %.0f MB/s\n",
      dd_before_mb_s, dd_after_mb_s, dd_mb_s);
  if (dd_mb_s > 0) std::printf("  ratio recorder / dd: %.2f\n", recorder_mb_s / dd_mb_s);
  if (drops > 0) std::printf("  losses by cause:\n%s", health.FinalReport().c_str());
  std::printf(
      "  CPU: %.2f cores on average (user + system of the whole process: grab threads, recorder "
      "writers, and the %s themselves)\n",
      cores_used, gentl ? "simulated producer's frame fills" : "in-memory cameras");
  return drops == 0 ? 0 : 1;
}
