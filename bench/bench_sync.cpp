// Vicon packet to FrameSet latency. A ViconUdpSender thread sends the Tracker
// object stream (3 objects per datagram) over loopback UDP to a
// ViconUdpSource; the receiving thread feeds every Vicon frame to a
// FrameSetAssembler whose camera frames for each trigger are already there,
// so the trigger's Vicon packet is the piece that completes its FrameSet.
// For the same (trigger) packets it measures, from the moment the sender hands the
// datagram to the kernel:
//   receive  until ViconUdpSource::Next returns the parsed, converted frame
//            (the baseline: what any consumer of the stream pays);
//   frameset until FrameSetAssembler::Poll returns the trigger's FrameSet.
// Prints p50/p99 of both, the FrameSet figure as a ratio of the baseline,
// and the synchronisation's drop counts (expected: none).
//
// Usage: bench_sync [packets (default 16000)] [rate_hz (default 2000)]
// The Vicon rate is raised from 80 Hz so a run takes seconds; the divider
// stays 8 (a FrameSet per 8 packets).

#include "bench/bench_usage.h"
#include "bench/paced_vicon.h"
#include "drivers/host_clock.h"
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"
#include "sync/frame_set_assembler.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <thread>
#include <vector>

namespace {

using namespace lifmcr;
using Clock = std::chrono::steady_clock;

std::int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

double Percentile(std::vector<std::int64_t> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(p * static_cast<double>(values.size() - 1) + 0.5);
  return static_cast<double>(values[index]);
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_sync [PACKETS >= 16 (default 16000)] [RATE_HZ > 0 (default 2000)]\n"
    "Vicon packet to FrameSet latency over loopback UDP: p50/p99 of receive (the baseline)\n"
    "and of the completed FrameSet, their ratio, and the synchronisation's drop counts.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  const int packets = argc > 1 ? std::atoi(argv[1]) : 16000;
  const double rate_hz = argc > 2 ? std::atof(argv[2]) : 2000.0;
  if (packets < 16 || !(rate_hz > 0)) {
    std::fprintf(stderr, "usage: bench_sync [packets >= 16] [rate_hz > 0]\n");
    return 2;
  }
  constexpr int kDivider = 8;
  constexpr std::int64_t kFirstFrame = 100000;
  const std::vector<std::string> objects = {"plate", "cam0", "cam1"};

  ViconUdpSourceOptions source_options;
  source_options.address = "127.0.0.1";
  source_options.port = 0;
  source_options.objects = objects;
  ViconUdpSource source(source_options);
  if (Status started = source.Start(); !started) {
    std::fprintf(stderr, "%s\n", started.error().message.c_str());
    return 1;
  }
  auto sender = ViconUdpSender::Open("127.0.0.1", source.BoundPort());
  if (!sender) {
    std::fprintf(stderr, "%s\n", sender.error().message.c_str());
    return 1;
  }

  FrameSetAssemblerOptions options;
  options.serials = {"cam0", "cam1"};
  options.vicon_divider = kDivider;
  options.vicon_rate_hz = rate_hz;
  options.trigger.trigger_period_ns = std::llround(1e9 * kDivider / rate_hz);
  // The first camera frames are those of the trigger on packet kDivider (the
  // receiver adds them one packet ahead): that is the assembler's trigger 0.
  options.vicon_f0 = kFirstFrame + kDivider;
  options.vicon_phase_tolerance_ns = 1'000'000'000;  // pacing jitter is not what is measured
  FrameSetAssembler assembler(options);

  std::vector<std::atomic<std::int64_t>> sent_ns(static_cast<std::size_t>(packets));
  std::thread sending([&] {
    const std::string error = bench::SendPacedVicon(*sender, objects, kFirstFrame, rate_hz, sent_ns);
    if (!error.empty()) std::fprintf(stderr, "%s\n", error.c_str());
  });

  std::vector<std::int64_t> receive_ns, frameset_ns, overhead_ns;
  receive_ns.reserve(packets);
  std::int64_t sets = 0;
  const std::int64_t period_ns = options.trigger.trigger_period_ns;
  while (true) {
    auto next = source.Next(std::chrono::milliseconds(500));
    if (!next || !next->has_value()) break;  // the sender is done (or failed)
    const std::int64_t received = NowNs();
    ViconFrame& frame = **next;
    const std::int64_t index = frame.vicon_frame - kFirstFrame;
    const std::int64_t sent = sent_ns[index].load(std::memory_order_acquire);
    // Camera frames of the next trigger, in before its Vicon packet arrives.
    if ((index + 1) % kDivider == 0 && index + 1 < packets) {
      const std::int64_t trigger = (index + 1) / kDivider;
      const std::int64_t host = HostRealtimeNs();
      for (int camera = 0; camera < 2; ++camera) {
        Frame camera_frame;
        camera_frame.camera_index = camera;
        // The 16-bit GigE Vision counter from 65400, skipping 0 on wrap.
        const std::int64_t id = 65400 + trigger;
        camera_frame.frame_id =
            static_cast<std::uint64_t>(id <= 65535 ? id : (id - 65536) % 65535 + 1);
        camera_frame.device_ns = 1'000'000'000 + trigger * period_ns;
        camera_frame.host_ns = host;
        assembler.AddFrame(std::move(camera_frame));
      }
    }
    const bool is_trigger = index % kDivider == 0;
    assembler.AddVicon(std::move(frame));
    std::vector<FrameSet> ready = assembler.Poll(HostRealtimeNs());
    const std::int64_t emitted = NowNs();
    for (const FrameSet& set : ready) {
      ++sets;
      if (is_trigger && set.vicon_frame == kFirstFrame + index) {
        receive_ns.push_back(received - sent);  // the baseline, for the same packets
        frameset_ns.push_back(emitted - sent);
        overhead_ns.push_back(emitted - received);
      }
    }
  }
  sending.join();
  for (FrameSet& set : assembler.Flush()) (void)set, ++sets;

  const ViconSourceStats stats = source.Stats();
  const double receive_p50 = Percentile(receive_ns, 0.5),
               receive_p99 = Percentile(receive_ns, 0.99);
  const double set_p50 = Percentile(frameset_ns, 0.5), set_p99 = Percentile(frameset_ns, 0.99);
  std::printf("bench_sync: %d Vicon packets at %.0f Hz over loopback UDP, divider %d, 2 cameras\n",
              packets, rate_hz, kDivider);
  std::printf("  received %llu frames (%llu malformed, %llu gaps), %lld FrameSets (%zu timed)\n",
              static_cast<unsigned long long>(stats.frames),
              static_cast<unsigned long long>(stats.malformed),
              static_cast<unsigned long long>(stats.gaps), static_cast<long long>(sets),
              frameset_ns.size());
  std::printf("  %-34s p50 %8.1f us   p99 %8.1f us\n", "packet -> ViconFrame (baseline)",
              receive_p50 / 1e3, receive_p99 / 1e3);
  std::printf("  %-34s p50 %8.1f us   p99 %8.1f us\n", "packet -> FrameSet", set_p50 / 1e3,
              set_p99 / 1e3);
  std::printf("  %-34s p50 %8.1f us   p99 %8.1f us\n", "  of which assembler (Add+Poll)",
              Percentile(overhead_ns, 0.5) / 1e3, Percentile(overhead_ns, 0.99) / 1e3);
  std::printf("  ratio FrameSet / baseline: p50 %.2fx, p99 %.2fx\n", set_p50 / receive_p50,
              set_p99 / receive_p99);
  std::printf("  sync drops: %s\n", assembler.drops().OneLine().c_str());
  return 0;
}
