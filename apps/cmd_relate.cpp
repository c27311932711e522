// `lifmcr relate`: c0_from_cx of a rig whose cameras are held by processes
// on several hosts (`replay`/`record --publish --cameras ...`), from the
// poses they publish on <PREFIX>_<SERIAL>_POSE.
//
// Why a command of its own rather than a rig-file field naming the process
// that relates: relating needs neither cameras, nor the map, nor any
// processing (only the poses on LCM), so it runs on whichever host the
// operator picks (the one running `lifmcr monitor`, or a camera host), is
// started and restarted on its own without re-arming any camera, and every
// camera process stays alike (a host's role is which cameras it holds).
// The rig file still configures it (`--rig`: LCM, camera 0, rigid-mount
// change detection), and a process holding every camera relates in-process
// as before (apps/pipeline/pipeline.h, PipelineOptions::relate), so no pair
// is related twice.
//
// Relate step: registration::ExtrinsicsRelater, the one the in-process
// pipeline's MapLocalizerStage::Relate uses; the message:
// Publisher::PublishExtrinsics. Pairing and its bounded wait:
// apps/pipeline/pose_pairing.h.

#include "apps/commands.h"
#include "apps/pipeline/live_registration.h"
#include "apps/pipeline/pose_pairing.h"
#include "apps/pipeline/publisher.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "drivers/host_clock.h"
#include "registration/live/extrinsics_monitor.h"

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::apps {
namespace {

std::atomic<bool> g_relate_stop{false};
void OnRelateSignal(int) { g_relate_stop = true; }

struct RelateArgs {
  std::string rig;
  std::string lcm_url;
  std::string prefix;
  std::string reference_serial;
  int wait_ms = 2000;
  std::string extrinsics_csv;
  bool rigid_mount = false;
  double idle_exit_s = 0;
  double duration_s = 0;
};

struct Relating {
  PosePairing pairing;
  registration::ExtrinsicsRelater relater;
  Publisher* publisher = nullptr;
  ExtrinsicsCsv* csv = nullptr;
  std::uint64_t published = 0, undecodable = 0;
  std::chrono::steady_clock::time_point last_pose{};
  bool any_pose = false;

  void OnPose(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
    auto pose = DecodePoseMessage(buffer->data, static_cast<int>(buffer->data_size));
    if (!pose) {
      ++undecodable;
      spdlog::warn("relate: {}: {}", channel, pose.error().message);
      return;
    }
    last_pose = std::chrono::steady_clock::now();
    any_pose = true;
    PosePairing::Added added = pairing.Add(*pose, HostRealtimeNs());
    if (!added.refused.empty()) std::cerr << "lifmcr relate: refused " << added.refused << "\n";
    for (const PosePair& pair : added.pairs) {
      ExtrinsicsRecord record{
          pair.reference.serial,
          pair.camera.serial,
          pair.camera.trigger_index,
          relater.Relate(pair.camera.serial, pair.reference.w0_from_cam, pair.camera.w0_from_cam),
          pair.camera.arrival_ns,
          pair.reference.w0_from_cam.localisation};
      publisher->PublishExtrinsics(record.reference_serial, record.serial, record.trigger_index,
                                   record.c0_from_cx);
      if (csv) csv->Write(record);
      ++published;
    }
  }
};

void OnPoseMessage(const lcm::ReceiveBuffer* buffer, const std::string& channel,
                   Relating* relating) {
  relating->OnPose(buffer, channel);
}

int RunRelate(const RelateArgs& args) {
  PublisherOptions publisher_options;
  registration::ExtrinsicsMonitorOptions monitor;
  bool rigid_mount = args.rigid_mount;
  std::string reference_serial = args.reference_serial;
  std::vector<std::string> cameras;  // the rig's: each expected of every trigger
  if (!args.rig.empty()) {
    auto rig = LoadRigConfig(args.rig);
    if (!rig) {
      std::cerr << "lifmcr relate: " << EscapeText(rig.error().message) << "\n";
      return 2;
    }
    publisher_options = PublisherOptions::FromRig(rig->lcm);
    publisher_options.publish_previews = false;
    rigid_mount = rigid_mount || rig->registration.rigid_mount;
    monitor.changed_after = rig->registration.changed_after;
    monitor.settle_triggers = rig->registration.settle_triggers;
    for (const CameraConfig& camera : rig->cameras) cameras.push_back(camera.serial);
    if (reference_serial.empty() && rig->ReferenceIndex() >= 0)
      reference_serial = rig->cameras[static_cast<std::size_t>(rig->ReferenceIndex())].serial;
  }
  if (!args.lcm_url.empty()) publisher_options.url = args.lcm_url;
  if (!args.prefix.empty()) publisher_options.channel_prefix = args.prefix;
  if (Status s = publisher_options.Check(); !s) {
    std::cerr << "lifmcr relate: " << EscapeText(s.error().message) << "\n";
    return 2;
  }
  PosePairingOptions pairing_options;
  pairing_options.reference_serial = reference_serial;
  pairing_options.wait = std::chrono::milliseconds(args.wait_ms);
  pairing_options.cameras = cameras;
  if (Status s = pairing_options.Check(); !s) {
    std::cerr << "lifmcr relate: " << s.error().message << "\n";
    return 2;
  }

  // The receiving side, as `lifmcr monitor` opens it: LCM's default URL
  // unless given, a receive buffer for bursts of several hosts' messages.
  std::string url = publisher_options.url;
  if (url.empty()) {
    const char* env = std::getenv("LCM_DEFAULT_URL");
    url = env ? env : "udpm://239.255.76.67:7667?ttl=0";
  }
  if (url.starts_with("udpm://") && url.find("recv_buf_size") == std::string::npos)
    url += std::string(url.find('?') == std::string::npos ? "?" : "&") + "recv_buf_size=4194304";
  lcm::LCM bus(url);
  if (!bus.good()) {
    std::cerr << "lifmcr relate: cannot open LCM '" << EscapeText(url) << "'\n";
    return 3;
  }
  auto publisher = Publisher::Create(publisher_options);
  if (!publisher) {
    std::cerr << "lifmcr relate: " << EscapeText(publisher.error().message) << "\n";
    return 3;
  }
  std::shared_ptr<ExtrinsicsCsv> csv;
  if (!args.extrinsics_csv.empty()) {
    auto made = ExtrinsicsCsv::Create(args.extrinsics_csv);
    if (!made) {
      std::cerr << "lifmcr relate: " << EscapeText(made.error().message) << "\n";
      return 3;
    }
    csv = std::move(*made);
  }
  Relating relating{PosePairing(pairing_options), {}, publisher->get(), csv.get()};
  if (rigid_mount) relating.relater.MonitorChanges(monitor);
  const std::string channels = publisher_options.channel_prefix + "_.*_POSE";
  bus.subscribeFunction(channels, &OnPoseMessage, &relating);

  g_relate_stop = false;
  std::signal(SIGINT, OnRelateSignal);
  std::signal(SIGTERM, OnRelateSignal);
  std::cerr << "lifmcr relate: pairing " << channels << " on " << url << ", camera 0 = "
            << (reference_serial.empty() ? std::string("the poses' map camera") : reference_serial)
            << ", waiting " << args.wait_ms << " ms per trigger"
            << (rigid_mount ? ", rigid-mount change detection" : "") << "\n";
  const auto start = std::chrono::steady_clock::now();
  std::string stop_why = "signal";
  while (!g_relate_stop) {
    bus.handleTimeout(50);
    for (const std::string& line : relating.pairing.Expire(HostRealtimeNs()))
      std::cerr << "lifmcr relate: " << line << "\n";
    const auto now = std::chrono::steady_clock::now();
    if (args.duration_s > 0 &&
        std::chrono::duration<double>(now - start).count() >= args.duration_s) {
      stop_why = "duration reached";
      break;
    }
    if (args.idle_exit_s > 0 && relating.any_pose &&
        std::chrono::duration<double>(now - relating.last_pose).count() >= args.idle_exit_s) {
      stop_why = "no pose for " + std::to_string(args.idle_exit_s) + " s";
      break;
    }
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  // What is still waiting at the end lacked a pose too.
  for (const std::string& line : relating.pairing.Flush())
    std::cerr << "lifmcr relate: " << line << "\n";
  std::cout << "stopped by: " << stop_why << "\n"
            << "extrinsics: " << relating.published << " published on "
            << publisher_options.channel_prefix << "_<SERIAL>_EXTRINSICS\n"
            << relating.pairing.Report() << "\n";
  if (relating.undecodable > 0)
    std::cout << "undecodable POSE messages: " << relating.undecodable << "\n";
  if (csv) std::cout << csv->rows() << " rows in " << csv->path().string() << "\n";
  const bool complete = relating.pairing.lacked().empty() && relating.pairing.refused() == 0 &&
                        relating.undecodable == 0;
  return complete ? 0 : 1;
}

}  // namespace

CommandRun AddRelateCommand(CLI::App& app) {
  auto args = std::make_shared<RelateArgs>();
  app.footer(
      "Relates the cameras of a rig held by processes on several hosts: each runs\n"
      "`lifmcr replay SEQ --cameras S...` or `lifmcr record --rig RIG --publish --cameras S...`\n"
      "with --reference MAP_DIR and publishes every pose w0_from_cam on\n"
      "<PREFIX>_<SERIAL>_POSE. This command pairs a trigger's pose of camera 0 (the map's\n"
      "camera) with each other camera's, composes c0_from_cx with its covariance (and, with\n"
      "--rigid-mount, the change detection's verdict) and publishes it on\n"
      "<PREFIX>_<SERIAL>_EXTRINSICS, the message a process holding every camera publishes.\n"
      "A trigger waits --wait-ms after its first pose for the others; a camera whose pose\n"
      "did not come is reported on stderr and counted. Run one per rig, on any host of its LAN.\n"
      "--rig RIG.yaml: lcm.url, lcm.channel_prefix, camera 0 (role reference) and\n"
      "registration.rigid_mount from the rig file (the flags override them), and its cameras,\n"
      "each expected of every trigger (without --rig: the cameras seen on the POSE channels).\n"
      "Stops on SIGINT/SIGTERM, after --duration, or --idle-exit seconds after the last pose.\n"
      "Reads: the <PREFIX>_<SERIAL>_POSE channels; --rig RIG.yaml.\n"
      "Writes: the EXTRINSICS channels; --extrinsics-csv FILE (registration.csv rows).\n"
      "Exit codes: 0 every trigger paired; 1 a trigger lacked a camera's pose or a pose was\n"
      "refused (late, twice, another map); 2 usage; 3 LCM or the CSV cannot be opened.");
  app.add_option("--rig", args->rig, "Rig file (lcm:, camera 0, registration:)")
      ->check(CLI::ExistingFile);
  app.add_option("--lcm", args->lcm_url, "LCM URL (default: the rig's, else LCM's)")
      ->check(LcmUrlCheck, "LCM URL");
  app.add_option("--prefix", args->prefix, "Channel prefix (default: the rig's, else LIFMCR)");
  app.add_option(
      "--reference-serial", args->reference_serial,
      "Camera 0 (default: the rig's reference camera, else the map camera the poses name)");
  app.add_option("--wait-ms", args->wait_ms, "How long a trigger waits for its cameras' poses")
      ->check(CLI::Range(1, 600000))
      ->capture_default_str();
  app.add_option("--extrinsics-csv", args->extrinsics_csv,
                 "Every published c0_from_cx as registration.csv rows (lifmcr evaluate)");
  app.add_flag("--rigid-mount", args->rigid_mount,
               "Flag a camera whose c0_from_cx leaves its running estimate");
  app.add_option("--idle-exit", args->idle_exit_s,
                 "Stop this many seconds after the last pose (0: never)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration", args->duration_s, "Seconds to run; 0 = until a signal")
      ->check(CLI::NonNegativeNumber);
  return [args] { return RunRelate(*args); };
}

}  // namespace lifmcr::apps
