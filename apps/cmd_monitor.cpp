// `lifmcr monitor`: a terminal view of the LIFMCR_* channels, refreshed in
// place (ANSI escapes only, so it works over ssh and in tmux), fitted to the
// terminal's size and redrawn when it changes (SIGWINCH; apps/terminal.h).
// Lines are laid out for 80 columns.

#include "apps/commands.h"
#include "apps/terminal.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "lcm_types/safe_decode.h"

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <iostream>
#include <lifmcr_lcm/camera_extrinsics_t.hpp>
#include <lifmcr_lcm/camera_pose_t.hpp>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/pipeline_stats_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <map>
#include <memory>
#include <optional>
#include <poll.h>
#include <sstream>
#include <termios.h>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

std::atomic<bool> g_stop{false};
std::atomic<bool> g_resized{false};
void OnSignal(int) { g_stop = true; }
void OnResize(int) { g_resized = true; }

double NowS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Message arrival times over the last few seconds.
class RateMeter {
 public:
  void Tick(double t) {
    times_.push_back(t);
    ++count_;
  }
  double Hz(double now) {
    while (!times_.empty() && times_.front() < now - kWindowS) times_.pop_front();
    return static_cast<double>(times_.size()) / kWindowS;
  }
  std::uint64_t count() const { return count_; }

 private:
  static constexpr double kWindowS = 3.0;
  std::deque<double> times_;
  std::uint64_t count_ = 0;
};

struct CameraView {
  RateMeter preview, depth, lens_depth, tf, extrinsics_rate;
  double last_latency_ms = 0;  // receive - utime of the last preview
  std::int64_t last_frame = -1;
  float valid_fraction = 0, min_v = 0, max_v = 0;
  std::optional<lifmcr_lcm::camera_extrinsics_t> extrinsics;
  // Its poses w0_from_cam on _POSE (a process holding only some of the
  // rig's cameras; `lifmcr relate` pairs them).
  RateMeter pose;
  std::optional<lifmcr_lcm::camera_pose_t> last_pose;
};

// Names from the network reach the terminal: escaped (config/text_escape.h).
void Sanitize(std::string* s) { *s = lifmcr::Excerpt(*s, 64); }
void Sanitize(lifmcr_lcm::preview_image_t* m) { Sanitize(&m->serial); }
void Sanitize(lifmcr_lcm::depth_image_t* m) { Sanitize(&m->serial); }
void Sanitize(lifmcr_lcm::camera_extrinsics_t* m) {
  for (std::string* s : {&m->reference_serial, &m->serial, &m->method, &m->localisation, &m->status})
    Sanitize(s);
}
void Sanitize(lifmcr_lcm::camera_pose_t* m) {
  for (std::string* s :
       {&m->serial, &m->reference_serial, &m->method, &m->localisation, &m->status})
    Sanitize(s);
}
void Sanitize(lifmcr_lcm::vicon_frame_t* m) {
  for (auto& o : m->objects) Sanitize(&o.name);
}
void Sanitize(lifmcr_lcm::pipeline_stats_t* m) {
  Sanitize(&m->source);
  Sanitize(&m->cameras);
  for (auto& s : m->stages) Sanitize(&s.name);
  for (auto& d : m->drops) Sanitize(&d.kind);
}

// Cameras and Vicon objects shown at most (a sender inventing names cannot
// grow the monitor's memory without bound).
constexpr std::size_t kMaxShown = 64;

class Monitor {
 public:
  // Raw subscription: messages are checked before the generated decode
  // (lcm_types/safe_decode.h), then escaped; malformed ones are counted.
  template <typename T, void (Monitor::*On)(const lcm::ReceiveBuffer*, const std::string&, const T*)>
  void Raw(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    std::optional<T> message = lifmcr_lcm::SafeDecode<T>(rbuf->data, rbuf->data_size);
    if (!message) {
      ++malformed_;
      return;
    }
    Sanitize(&*message);
    (this->*On)(rbuf, channel, &*message);
  }

  void OnPreview(const lcm::ReceiveBuffer* rbuf, const std::string& channel,
                 const lifmcr_lcm::preview_image_t* m) {
    if (!Known(m->serial)) return;
    CameraView& c = cameras_[m->serial];
    const bool tf = channel.size() > 3 && channel.compare(channel.size() - 3, 3, "_TF") == 0;
    (tf ? c.tf : c.preview).Tick(NowS());
    if (!tf) {
      c.last_latency_ms = static_cast<double>(rbuf->recv_utime - m->utime) / 1e3;
      c.last_frame = m->frame_id;
    }
  }
  void OnDepth(const lcm::ReceiveBuffer*, const std::string&, const lifmcr_lcm::depth_image_t* m) {
    if (!Known(m->serial)) return;
    CameraView& c = cameras_[m->serial];
    // The per-lens maps (every frame processing takes) have a rate of their
    // own; coverage and range are the dense map's.
    if (m->geometry == lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID) {
      c.lens_depth.Tick(NowS());
      return;
    }
    c.depth.Tick(NowS());
    c.valid_fraction = m->valid_fraction;
    c.min_v = m->min_value;
    c.max_v = m->max_value;
  }
  void OnExtrinsics(const lcm::ReceiveBuffer*, const std::string&,
                    const lifmcr_lcm::camera_extrinsics_t* m) {
    if (!Known(m->serial)) return;
    CameraView& c = cameras_[m->serial];
    c.extrinsics = *m;
    c.extrinsics_rate.Tick(NowS());
  }
  void OnPose(const lcm::ReceiveBuffer*, const std::string&, const lifmcr_lcm::camera_pose_t* m) {
    if (!Known(m->serial)) return;
    CameraView& c = cameras_[m->serial];
    c.last_pose = *m;
    c.pose.Tick(NowS());
  }
  void OnVicon(const lcm::ReceiveBuffer*, const std::string&, const lifmcr_lcm::vicon_frame_t* m) {
    vicon_.Tick(NowS());
    last_vicon_ = *m;
    for (const auto& o : m->objects)
      if (o.occluded && (occlusions_.size() < kMaxShown || occlusions_.count(o.name)))
        ++occlusions_[o.name];
  }
  void OnStats(const lcm::ReceiveBuffer*, const std::string&,
               const lifmcr_lcm::pipeline_stats_t* m) {
    // One block per process (a rig on several hosts has one per host).
    if (stats_.size() < kMaxHosts || stats_.count(m->source)) stats_[m->source] = *m;
  }

  std::string Render(const std::string& url) {
    const double now = NowS();
    std::ostringstream out;
    char line[512];
    out << "lifmcr monitor  " << (url.empty() ? "LCM default URL" : url)
        << "   (q or Ctrl-C quits)\n\n";
    // 79 columns: camera, rates (Hz; lens: per-lens depth maps), latency
    // (ms), last frame, depth %, range.
    std::snprintf(line, sizeof line, "%-10s %7s %8s %5s %6s %10s %6s %6s %13s\n", "camera",
                  "prev Hz", "depth Hz", "lens", "TF Hz", "latency ms", "frame", "depth%",
                  "virtual depth");
    out << line;
    if (cameras_.empty()) out << "  (no camera channel yet)\n";
    for (auto& [serial, c] : cameras_) {
      std::snprintf(
          line, sizeof line, "%-10.10s %7.1f %8.1f %5.1f %6.1f %10.1f %6lld %6.1f %6.2f..%-5.2f\n",
          serial.c_str(), c.preview.Hz(now), c.depth.Hz(now), c.lens_depth.Hz(now), c.tf.Hz(now),
          c.last_latency_ms,
          static_cast<long long>(c.last_frame), 100.0 * c.valid_fraction, c.min_v, c.max_v);
      out << line;
    }
    bool any_pose = false;
    for (auto& [serial, c] : cameras_) {
      if (!c.last_pose) continue;
      if (!any_pose) out << "\nposes (w0_from_cam, for lifmcr relate)\n";
      any_pose = true;
      const auto& p = *c.last_pose;
      std::snprintf(line, sizeof line, "  %-10.10s %5.1f Hz trigger %lld [%s] inliers %d %s\n",
                    serial.c_str(), c.pose.Hz(now), static_cast<long long>(p.trigger_index),
                    p.localisation.c_str(), p.inliers, p.status.c_str());
      out << line;
    }
    bool any_extrinsics = false;
    for (auto& [serial, c] : cameras_) {
      if (!c.extrinsics) continue;
      if (!any_extrinsics) out << "\nextrinsics (c0_from_cx)\n";
      any_extrinsics = true;
      const auto& e = *c.extrinsics;
      std::snprintf(line, sizeof line,
                    "  %s <- %s %.1f Hz trigger %lld [%s %s] inliers %d rmse %.2f px %s\n"
                    "    t = (%.1f, %.1f, %.1f) mm  q = (%.4f, %.4f, %.4f, %.4f)\n",
                    e.reference_serial.c_str(), e.serial.c_str(), c.extrinsics_rate.Hz(now),
                    static_cast<long long>(e.trigger_index), e.method.c_str(),
                    e.localisation.c_str(), e.inliers, e.rmse_px, e.status.c_str(), e.t_mm[0],
                    e.t_mm[1], e.t_mm[2], e.q_wxyz[0], e.q_wxyz[1], e.q_wxyz[2], e.q_wxyz[3]);
      out << line;
      if (e.change_state != lifmcr_lcm::camera_extrinsics_t::CHANGE_OFF) {
        static const char* const kStates[] = {"off", "settling", "steady", "departing",
                                              "CHANGED: camera moved on its mount"};
        const int state = e.change_state >= 0 && e.change_state <= 4 ? e.change_state : 0;
        std::snprintf(line, sizeof line,
                      "    mount %s (departure %.1f, %d in a row; running t = (%.1f, %.1f, %.1f) "
                      "mm)\n",
                      kStates[state], e.departure, e.departures_in_row, e.running_t_mm[0],
                      e.running_t_mm[1], e.running_t_mm[2]);
        out << line;
      }
    }
    std::snprintf(line, sizeof line, "\nVicon   %6.1f Hz  frames %llu", vicon_.Hz(now),
                  static_cast<unsigned long long>(vicon_.count()));
    out << line;
    if (last_vicon_) out << "  last frame " << last_vicon_->vicon_frame;
    out << "\n";
    if (last_vicon_)
      for (const auto& o : last_vicon_->objects) {
        std::snprintf(line, sizeof line, "  %-10s %s  occluded in %llu frames\n", o.name.c_str(),
                      o.occluded ? "OCCLUDED" : "tracked ",
                      static_cast<unsigned long long>(occlusions_[o.name]));
        out << line;
      }
    if (malformed_ > 0) out << "malformed messages ignored: " << malformed_ << "\n";
    if (stats_.empty()) out << "\npipeline  (no LIFMCR_STATS yet)\n";
    for (const auto& [source, stats] : stats_) {
      std::snprintf(line, sizeof line, "\npipeline %s, cameras %s (stats %.1f s ago)\n",
                    source.empty() ? "(unnamed)" : source.c_str(), stats.cameras.c_str(),
                    now - static_cast<double>(stats.utime) / 1e6);
      out << line;
      for (const auto& st : stats.stages) {
        std::snprintf(line, sizeof line,
                      "  %-12.12s %5.1f Hz q %d/%d p50 %6.1f p99 %6.1f ms done %lld skip %lld\n",
                      st.name.c_str(), st.rate_hz, st.queue_depth, st.queue_capacity,
                      st.latency_p50_ms, st.latency_p99_ms, static_cast<long long>(st.processed),
                      static_cast<long long>(st.skipped));
        out << line;
      }
      out << "  drops:";
      if (stats.drops.empty()) out << " none";
      for (const auto& d : stats.drops) out << " " << d.kind << "=" << d.count;
      out << "\n";
    }
    return out.str();
  }

 private:
  bool Known(const std::string& serial) const {
    return cameras_.size() < kMaxShown || cameras_.count(serial) != 0;
  }

  std::uint64_t malformed_ = 0;
  std::map<std::string, CameraView> cameras_;
  RateMeter vicon_;
  std::optional<lifmcr_lcm::vicon_frame_t> last_vicon_;
  std::map<std::string, std::uint64_t> occlusions_;
  // By source ("<host>:<pid>"): one pipeline per host of the rig.
  static constexpr std::size_t kMaxHosts = 16;
  std::map<std::string, lifmcr_lcm::pipeline_stats_t> stats_;
};

struct Args {
  std::string lcm_url;
  double duration_s = 0;
};

int RunMonitor(const Args& args) {
  // Messages are at most ~90 KB (bench/bench_lcm_sizes.cpp), but a burst of
  // several cameras' messages exceeds a stock 208 KB buffer when the view is
  // being drawn: ask for 4 MB (granted up to net.core.rmem_max).
  std::string url = args.lcm_url;
  if (url.empty()) {
    const char* env = std::getenv("LCM_DEFAULT_URL");
    url = env ? env : "udpm://239.255.76.67:7667?ttl=0";
  }
  if (url.starts_with("udpm://") && url.find("recv_buf_size") == std::string::npos)
    url += std::string(url.find('?') == std::string::npos ? "?" : "&") + "recv_buf_size=4194304";
  lcm::LCM bus(url);
  if (!bus.good()) {
    std::cerr << "lifmcr monitor: cannot open LCM '" << EscapeText(args.lcm_url) << "'\n";
    return 3;
  }
  Monitor monitor;
  using namespace lifmcr_lcm;
  bus.subscribe("LIFMCR_.*_PREVIEW", &Monitor::Raw<preview_image_t, &Monitor::OnPreview>, &monitor);
  bus.subscribe("LIFMCR_.*_TF", &Monitor::Raw<preview_image_t, &Monitor::OnPreview>, &monitor);
  bus.subscribe("LIFMCR_.*_DEPTH", &Monitor::Raw<depth_image_t, &Monitor::OnDepth>, &monitor);
  bus.subscribe("LIFMCR_.*_EXTRINSICS", &Monitor::Raw<camera_extrinsics_t, &Monitor::OnExtrinsics>,
                &monitor);
  bus.subscribe("LIFMCR_.*_POSE", &Monitor::Raw<camera_pose_t, &Monitor::OnPose>, &monitor);
  bus.subscribe("LIFMCR_VICON", &Monitor::Raw<vicon_frame_t, &Monitor::OnVicon>, &monitor);
  bus.subscribe("LIFMCR_STATS", &Monitor::Raw<pipeline_stats_t, &Monitor::OnStats>, &monitor);

  g_stop = false;
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  std::signal(SIGWINCH, OnResize);
  const bool tty_out = isatty(STDOUT_FILENO) == 1;
  const bool tty_in = isatty(STDIN_FILENO) == 1;
  termios saved{};
  if (tty_in) {
    tcgetattr(STDIN_FILENO, &saved);
    termios raw = saved;
    raw.c_lflag &= ~static_cast<tcflag_t>(ICANON | ECHO);
    raw.c_cc[VMIN] = 0;
    raw.c_cc[VTIME] = 0;
    tcsetattr(STDIN_FILENO, TCSANOW, &raw);
  }
  if (tty_out) std::cout << "\x1b[?25l\x1b[2J" << std::flush;  // hide cursor, clear
  TerminalSize size = QueryTerminalSize(STDOUT_FILENO);
  const auto start = std::chrono::steady_clock::now();
  auto next_draw = start;
  while (!g_stop) {
    bus.handleTimeout(50);
    if (tty_in) {
      pollfd fd{STDIN_FILENO, POLLIN, 0};
      if (poll(&fd, 1, 0) > 0) {
        char c = 0;
        if (read(STDIN_FILENO, &c, 1) == 1 && (c == 'q' || c == 'Q')) break;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (args.duration_s > 0 &&
        std::chrono::duration<double>(now - start).count() >= args.duration_s)
      break;
    if (tty_out && g_resized.exchange(false)) {
      size = QueryTerminalSize(STDOUT_FILENO);
      std::cout << "\x1b[2J";
      next_draw = now;  // at once, at the new size
    }
    if (tty_out && now >= next_draw) {
      std::cout << DrawFrame(FitToTerminal(monitor.Render(args.lcm_url), size)) << std::flush;
      next_draw = now + std::chrono::milliseconds(500);
    }
  }
  if (tty_in) tcsetattr(STDIN_FILENO, TCSANOW, &saved);
  if (tty_out)
    std::cout << "\x1b[?25h\n" << std::flush;
  else
    std::cout << monitor.Render(args.lcm_url) << std::flush;  // one view at the end
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGWINCH, SIG_DFL);
  return 0;
}

}  // namespace

CommandRun AddMonitorCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.footer(
      "A terminal view of the LIFMCR_* LCM channels, refreshed in place twice a second:\n"
      "per camera the preview, depth, per-lens depth (lens) and TF rates, latency\n"
      "(receipt - publication), last frame, depth coverage and range; the latest\n"
      "extrinsics when published; the\n"
      "Vicon rate and occlusions per object; the pipeline's stages and drops from\n"
      "LIFMCR_STATS. q or Ctrl-C quits. The view fits the terminal (80x24 and up; lines\n"
      "are clipped, a note says how many lines do not fit) and is redrawn when it is\n"
      "resized. Without a terminal on stdout it prints one view when it ends (--duration).\n"
      "Reads: the LCM bus (--lcm, else LCM_DEFAULT_URL, else LCM's default). Writes: the\n"
      "terminal only. Exit codes: 0 quit by q, a signal or --duration; 2 usage error;\n"
      "3 the LCM URL cannot be opened.");
  app.add_option("--lcm", args->lcm_url, "LCM URL (default: LCM's)")
      ->check(LcmUrlCheck, "LCM URL");
  app.add_option("--duration", args->duration_s, "Quit after this many seconds (0: never)")
      ->check(CLI::NonNegativeNumber);
  return [args] { return RunMonitor(*args); };
}

}  // namespace lifmcr::apps
