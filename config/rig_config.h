#pragma once
// The rig and pipeline configuration: plain structs with their defaults, the
// checks between fields, and the YAML loader and writer. Every field, its
// unit, default and allowed values are documented in config/README.md; the
// defaults are stated once, here, in the member initialisers.
//
// Paths (mla_file, cti, vicon csv/vsk, recorder out_dir) are stored resolved
// against the folder of the rig file, so a RigConfig never depends on the
// working directory. FormatRigConfig writes them resolved, which is why a
// formatted rig (copied into a recording) loads back equal from anywhere.
//
// Files: LoadRigConfig/ParseRigConfig require the files the pipeline reads
// (MLA XML, Vicon CSV, VSK) to exist. Device files (a GenTL producer .cti)
// are checked by the driver when it opens the device, because the machine
// that edits or replays a rig file is often not the one with the grabber.

#include "config/error.h"
#include "config/frames.h"
#include "config/image.h"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr {

// The reference camera defines the rig frame c0; every registered camera is
// registered to it (c0_from_cx).
enum class CameraRole { kReference, kRegistered };
// aravis: GigE/USB3 Vision through Aravis; gentl: a frame grabber's GenTL
// producer (CoaXPress); replay: a recorded sequence stands in for the camera.
enum class DriverKind { kAravis, kGenTl, kReplay };
// hardware: a pulse on a line (Vicon Lock Lab); software: lifmcr issues
// TriggerSoftware; free_run: the camera runs at its own rate.
enum class TriggerMode { kHardware, kSoftware, kFreeRun };
enum class TriggerActivation { kRisingEdge, kFallingEdge };
// GenICam PixelFormat names the driver sets. Bayer mosaics travel as 8-bit
// grey buffers; RGB8 is not offered because lifmcr buffers hold BGR order and
// accepting RGB would force a channel swap (a copy) on every frame.
enum class CameraPixelFormat { kMono8, kBgr8, kBayerRg8, kBayerGr8, kBayerGb8, kBayerBg8 };
// Named ...Kind so it does not collide with the drivers/ ViconSource interface.
enum class ViconSourceKind { kNone, kUdp, kCsv };
// newest_wins: a busy stage drops the older waiting frame set (counted);
// block: the stage waits, back-pressuring the queue before it (replay).
enum class SkipPolicy { kNewestWins, kBlock };

// Names as written in rig files; Parse* returns nullopt for anything else,
// *Names() gives the allowed names as "a|b|c" for messages.
std::optional<CameraRole> ParseCameraRole(std::string_view name);
std::string_view ToString(CameraRole value);
std::string CameraRoleNames();
std::optional<DriverKind> ParseDriverKind(std::string_view name);
std::string_view ToString(DriverKind value);
std::string DriverKindNames();
std::optional<TriggerMode> ParseTriggerMode(std::string_view name);
std::string_view ToString(TriggerMode value);
std::string TriggerModeNames();
std::optional<TriggerActivation> ParseTriggerActivation(std::string_view name);
std::string_view ToString(TriggerActivation value);
std::string TriggerActivationNames();
std::optional<CameraPixelFormat> ParseCameraPixelFormat(std::string_view name);
std::string_view ToString(CameraPixelFormat value);
std::string CameraPixelFormatNames();
std::optional<ViconSourceKind> ParseViconSource(std::string_view name);
std::string_view ToString(ViconSourceKind value);
std::string ViconSourceNames();
std::optional<SkipPolicy> ParseSkipPolicy(std::string_view name);
std::string_view ToString(SkipPolicy value);
std::string SkipPolicyNames();

// The layout of a frame in lifmcr buffers: Bayer and Mono8 as kMono8, BGR8 as kBgr8.
PixelFormat BufferPixelFormat(CameraPixelFormat format);

struct DriverConfig {
  DriverKind kind = DriverKind::kAravis;
  std::string address;        // aravis: device id, serial or IP; empty = find by camera serial
  // gentl: the producer .cti; empty = every .cti in GENICAM_GENTL64_PATH
  std::filesystem::path cti;
  std::string interface_id;  // gentl `interface`: the producer's interface id; empty = any
  std::string device;        // gentl: device id or serial; empty = find by the camera's serial
  bool loop = false;          // replay: start the sequence again after its last frame
  bool operator==(const DriverConfig&) const = default;
};

struct TriggerConfig {
  TriggerMode mode = TriggerMode::kHardware;
  std::string source = "Line1";  // GenICam TriggerSource used in hardware mode
  TriggerActivation activation = TriggerActivation::kRisingEdge;
  bool operator==(const TriggerConfig&) const = default;
};

// Sensor region of interest, in pixels of the full sensor.
struct RoiConfig {
  int x_px = 0;
  int y_px = 0;
  int width_px = 0;   // > 0
  int height_px = 0;  // > 0
  bool operator==(const RoiConfig&) const = default;
};

struct CameraConfig {
  std::string serial;  // as in TypeE_<serial>; digits allowed, kept as text
  std::string name;    // short unique name (cam0); used in channel names and logs
  CameraRole role = CameraRole::kRegistered;
  DriverConfig driver;
  std::filesystem::path mla_file;  // RayCalibData XML of this camera
  TriggerConfig trigger;
  double exposure_us = 10000.0;  // > 0
  double gain_db = 0.0;          // >= 0
  CameraPixelFormat pixel_format = CameraPixelFormat::kMono8;
  std::optional<RoiConfig> roi;          // none = full sensor
  int packet_size_bytes = 0;             // aravis GigE packet size; 0 = negotiate
  std::int64_t socket_buffer_bytes = 0;  // aravis GigE socket buffer; 0 = auto (payload size)
  std::string vicon_object;              // object name in the Vicon stream/CSV; empty = not tracked
  // The clock its frames' device timestamps are on: cameras naming the same
  // clock (PTP-synchronised, stamped by one frame grabber) are placed on the
  // trigger count against each other by device time; empty = the driver's
  // own (a clock of the camera's own, or the sequence's for replay).
  std::string device_clock;
  bool operator==(const CameraConfig&) const = default;
};

struct ViconUdpConfig {
  std::string address = "0.0.0.0";  // local IPv4 address to receive the Tracker stream on
  int port = 51001;                 // 1..65535
  bool operator==(const ViconUdpConfig&) const = default;
};

// The slowest Vicon frame rate and the longest camera trigger period
// (trigger_divider / rate_hz) a rig file may give; real systems run at tens
// to thousands of Hz and trigger cameras several times a second.
inline constexpr double kMinViconRateHz = 1.0;
inline constexpr double kMaxTriggerPeriodS = 60.0;

struct ViconConfig {
  ViconSourceKind source = ViconSourceKind::kNone;
  ViconUdpConfig udp;
  std::filesystem::path csv;  // source csv: the Tracker CSV export to replay
  // A Vicon CSV does not state how RX, RY, RZ encode the rotation; Tracker's
  // default export is helical (axis * angle) in radians.
  RotationRepresentation rotation = RotationRepresentation::kHelicalRad;
  // The paper: LiFMCR's Vicon data is left-handed (config/README.md, "Vicon
  // handedness", says why y is the mirrored axis by default).
  Handedness handedness = Handedness::kLeftFlipY;
  std::string plate_object = "plate";  // the world-defining marker plate
  double rate_hz = 80.0;               // Vicon frame rate, kMinViconRateHz .. 10000
  int trigger_divider = 8;             // Vicon frames per camera trigger, 1 .. 10000
  std::filesystem::path vsk;           // optional object model (Object.vsk)
  bool operator==(const ViconConfig&) const = default;
};

struct RecorderConfig {
  std::filesystem::path out_dir;   // empty = given on the command line (--out)
  int queue_frames = 16;           // frames buffered per camera, >= 1
  int writer_threads = 1;          // 1..64
  bool direct_io = true;           // O_DIRECT writes (no page-cache copy)
  int direct_io_min_kb = 1024;     // frames smaller than this go through the page cache
  std::int64_t max_memory_mb = 0;  // cap on buffered frames, MiB; 0 = queue_frames alone
  bool operator==(const RecorderConfig&) const = default;
};

struct ProcessingConfig {
  bool enabled = true;
  int threads = 0;  // 0 = all cores
  SkipPolicy skip_policy = SkipPolicy::kNewestWins;
  int preview_max_px = 1024;  // longest side of published previews, 16..8192
  bool operator==(const ProcessingConfig&) const = default;
};

struct LcmConfig {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";  // LCM provider URL
  std::string channel_prefix = "LIFMCR";                // [A-Z0-9_]+
  bool publish_previews = true;
  bool operator==(const LcmConfig&) const = default;
};

// Live registration (`lifmcr record --publish --reference MAP_DIR`).
struct RegistrationConfig {
  // The cameras sit rigidly on the rig: c0_from_cx should not change, and a
  // run of changed_after triggers departing from its running estimate beyond
  // its uncertainty is flagged (registration/live/extrinsics_monitor.h).
  bool rigid_mount = false;
  int changed_after = 3;     // 1..100
  int settle_triggers = 10;  // 2..1000: triggers that make the first running estimate
  bool operator==(const RegistrationConfig&) const = default;
};

// A problem found by RigConfig::FindIssue: the key path of the offending
// value (as in the YAML, "/cameras/1/serial") and what was expected.
struct ConfigIssue {
  std::string path;
  std::string what;
};

struct RigConfig {
  std::string name;
  std::vector<CameraConfig> cameras;  // at least one, exactly one reference
  ViconConfig vicon;
  RecorderConfig recorder;
  ProcessingConfig processing;
  LcmConfig lcm;
  RegistrationConfig registration;

  // Value ranges and cross-field rules (unique serials, names and Vicon
  // objects, one reference, driver fields matching the driver kind, ...).
  // Touches no files. The loader turns the issue path back into a line.
  std::optional<ConfigIssue> FindIssue() const;
  // FindIssue as a Status: "<rig 'name'>: <path>: <what>".
  Status Check() const;
  // Index of the reference camera, -1 when there is none.
  int ReferenceIndex() const;

  bool operator==(const RigConfig&) const = default;
};

// What is wrong with an LCM provider URL (`lcm.url`, `--lcm`): the provider,
// the udpm:// group (multicast IPv4) and port, the tcpq:// host and port, the
// options each provider takes and their values; nullopt for a URL LCM opens.
std::optional<std::string> LcmUrlProblem(std::string_view url);

// Parses and checks a rig file. `base_dir` resolves relative paths; `label`
// names the source in messages (the file path, usually).
Expected<RigConfig> ParseRigConfig(std::string_view yaml, const std::filesystem::path& base_dir,
                                   const std::string& label);
// A rig file of a few cameras is ~2 KB; 1 MiB bounds what is read.
inline constexpr std::uint64_t kRigFileMaxBytes = 1 << 20;
// Reads `path` (config/input_file.h: a regular file, at most
// kRigFileMaxBytes, UTF-8) and parses it with base_dir = its folder and
// label = path.
Expected<RigConfig> LoadRigConfig(const std::filesystem::path& path);
// YAML that ParseRigConfig reads back equal: every field written, including
// defaults, paths as stored (resolved), strings double-quoted.
std::string FormatRigConfig(const RigConfig& rig);

}  // namespace lifmcr
