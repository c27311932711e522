#include "config/rig_config.h"

#include "config/input_file.h"
#include "config/text_escape.h"

#include "config/yaml_reader.h"

#include <arpa/inet.h>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <system_error>
#include <utility>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

template <typename Enum, std::size_t N>
struct EnumNames {
  std::array<std::pair<Enum, std::string_view>, N> entries;

  std::optional<Enum> Parse(std::string_view name) const {
    for (const auto& [value, text] : entries)
      if (text == name) return value;
    return std::nullopt;
  }
  std::string_view Name(Enum value) const {
    for (const auto& [v, text] : entries)
      if (v == value) return text;
    return "?";
  }
  std::string All() const {
    std::string all;
    for (const auto& [value, text] : entries) all += (all.empty() ? "" : "|") + std::string(text);
    return all;
  }
};

constexpr EnumNames<CameraRole, 2> kRoleNames{{{
    {CameraRole::kReference, "reference"},
    {CameraRole::kRegistered, "registered"},
}}};
constexpr EnumNames<DriverKind, 3> kDriverNames{{{
    {DriverKind::kAravis, "aravis"},
    {DriverKind::kGenTl, "gentl"},
    {DriverKind::kReplay, "replay"},
}}};
constexpr EnumNames<TriggerMode, 3> kTriggerModeNames{{{
    {TriggerMode::kHardware, "hardware"},
    {TriggerMode::kSoftware, "software"},
    {TriggerMode::kFreeRun, "free_run"},
}}};
constexpr EnumNames<TriggerActivation, 2> kActivationNames{{{
    {TriggerActivation::kRisingEdge, "rising_edge"},
    {TriggerActivation::kFallingEdge, "falling_edge"},
}}};
constexpr EnumNames<CameraPixelFormat, 6> kPixelFormatNames{{{
    {CameraPixelFormat::kMono8, "Mono8"},
    {CameraPixelFormat::kBgr8, "BGR8"},
    {CameraPixelFormat::kBayerRg8, "BayerRG8"},
    {CameraPixelFormat::kBayerGr8, "BayerGR8"},
    {CameraPixelFormat::kBayerGb8, "BayerGB8"},
    {CameraPixelFormat::kBayerBg8, "BayerBG8"},
}}};
constexpr EnumNames<ViconSourceKind, 3> kViconSourceNames{{{
    {ViconSourceKind::kNone, "none"},
    {ViconSourceKind::kUdp, "udp"},
    {ViconSourceKind::kCsv, "csv"},
}}};
constexpr EnumNames<SkipPolicy, 2> kSkipPolicyNames{{{
    {SkipPolicy::kNewestWins, "newest_wins"},
    {SkipPolicy::kBlock, "block"},
}}};

std::string HandednessNames() {
  std::string all;
  for (const Handedness h : {Handedness::kRight, Handedness::kLeftFlipX, Handedness::kLeftFlipY,
                             Handedness::kLeftFlipZ}) {
    all += (all.empty() ? "" : "|") + std::string(ToString(h));
  }
  return all;
}

// ---------------------------------------------------------------- checks

bool IsIdentifier(const std::string& text) {
  if (text.empty()) return false;
  for (const char c : text) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

bool HasControlCharacter(const std::string& text) {
  for (const char c : text)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return true;
  return false;
}

bool IsIpv4(const std::string& text) {
  in_addr address{};
  return inet_pton(AF_INET, text.c_str(), &address) == 1;
}

std::string Quoted(const std::string& text) { return "'" + text + "'"; }

std::string NumberText(double value) {
  std::array<char, 64> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return std::string(buffer.data(), result.ptr);
}

// Decimal digits only, as a whole number in [min, max].
bool IsIntegerIn(std::string_view text, long long min, long long max) {
  if (text.empty() || text.size() > 18 || text.find_first_not_of("0123456789") != std::string_view::npos)
    return false;
  long long value = 0;
  std::from_chars(text.data(), text.data() + text.size(), value);
  return value >= min && value <= max;
}

// "HOST:PORT" or "HOST" of a URL's network part; the port 1..65535.
bool IsPortText(std::string_view text) { return IsIntegerIn(text, 1, 65535); }

// Checks a free-text field: not empty (when required), no control characters.
std::optional<ConfigIssue> CheckText(const std::string& path, const std::string& text,
                                     bool required) {
  if (required && text.empty()) return ConfigIssue{path, "expected a non-empty string"};
  if (HasControlCharacter(text))
    return ConfigIssue{path, "expected text without control characters"};
  return std::nullopt;
}

std::optional<ConfigIssue> CheckDriver(const std::string& at, const DriverConfig& driver) {
  const std::string kind(ToString(driver.kind));
  if (driver.kind != DriverKind::kAravis && !driver.address.empty())
    return ConfigIssue{at + "/address", "only the aravis driver takes an address, kind is " + kind};
  if (driver.kind == DriverKind::kAravis && HasControlCharacter(driver.address))
    return ConfigIssue{at + "/address", "expected text without control characters"};
  if (driver.kind != DriverKind::kGenTl && !driver.cti.empty())
    return ConfigIssue{at + "/cti", "only the gentl driver takes a cti, kind is " + kind};
  if (driver.kind != DriverKind::kReplay && driver.loop)
    return ConfigIssue{at + "/loop", "only the replay driver loops, kind is " + kind};
  if (driver.kind != DriverKind::kGenTl && !driver.interface_id.empty())
    return ConfigIssue{at + "/interface",
                       "only the gentl driver takes an interface, kind is " + kind};
  if (driver.kind != DriverKind::kGenTl && !driver.device.empty())
    return ConfigIssue{at + "/device", "only the gentl driver takes a device, kind is " + kind};
  if (HasControlCharacter(driver.interface_id))
    return ConfigIssue{at + "/interface", "expected text without control characters"};
  if (HasControlCharacter(driver.device))
    return ConfigIssue{at + "/device", "expected text without control characters"};
  return std::nullopt;
}

std::optional<ConfigIssue> CheckCamera(const std::string& at, const CameraConfig& camera) {
  if (!IsIdentifier(camera.serial))
    return ConfigIssue{
        at + "/serial",
        "expected letters, digits, '_' or '-' (it names TypeE_<serial> files), got " +
            Quoted(camera.serial)};
  if (!IsIdentifier(camera.name))
    return ConfigIssue{
        at + "/name",
        "expected letters, digits, '_' or '-' (it names LCM channels), got " + Quoted(camera.name)};
  if (auto issue = CheckDriver(at + "/driver", camera.driver)) return issue;
  if (camera.mla_file.empty())
    return ConfigIssue{at + "/mla_file", "expected the path of the camera's RayCalibData XML"};
  if (!IsIdentifier(camera.trigger.source))
    return ConfigIssue{at + "/trigger/source",
                       "expected a GenICam TriggerSource name such as Line1, got " +
                           Quoted(camera.trigger.source)};
  // Upper bounds: what a real camera can be set to (config/README.md).
  if (!std::isfinite(camera.exposure_us) || camera.exposure_us <= 0.0 ||
      camera.exposure_us > 1e7)
    return ConfigIssue{at + "/exposure_us", "expected a number > 0 and <= 1e7 (microseconds), got " +
                                                NumberText(camera.exposure_us)};
  if (!std::isfinite(camera.gain_db) || camera.gain_db < 0.0 || camera.gain_db > 100.0)
    return ConfigIssue{at + "/gain_db",
                       "expected a number 0 .. 100 (dB), got " + NumberText(camera.gain_db)};
  if (camera.roi) {
    const RoiConfig& roi = *camera.roi;
    if (roi.x_px < 0)
      return ConfigIssue{at + "/roi/x", "expected >= 0, got " + std::to_string(roi.x_px)};
    if (roi.y_px < 0)
      return ConfigIssue{at + "/roi/y", "expected >= 0, got " + std::to_string(roi.y_px)};
    if (roi.width_px <= 0)
      return ConfigIssue{at + "/roi/width", "expected > 0, got " + std::to_string(roi.width_px)};
    if (roi.height_px <= 0)
      return ConfigIssue{at + "/roi/height", "expected > 0, got " + std::to_string(roi.height_px)};
    constexpr long long kMaxSensorPx = 32768;  // replay/bmp.h kBmpLimits
    if (static_cast<long long>(roi.x_px) + roi.width_px > kMaxSensorPx)
      return ConfigIssue{at + "/roi/width", "expected x + width <= 32768 px (a real sensor), got " +
                                                std::to_string(static_cast<long long>(roi.x_px) +
                                                               roi.width_px)};
    if (static_cast<long long>(roi.y_px) + roi.height_px > kMaxSensorPx)
      return ConfigIssue{at + "/roi/height",
                         "expected y + height <= 32768 px (a real sensor), got " +
                             std::to_string(static_cast<long long>(roi.y_px) + roi.height_px)};
  }
  const bool aravis = camera.driver.kind == DriverKind::kAravis;
  if (camera.packet_size_bytes != 0 &&
      (camera.packet_size_bytes < 576 || camera.packet_size_bytes > 65535))
    return ConfigIssue{at + "/packet_size", "expected 0 (negotiate) or 576..65535 bytes, got " +
                                                std::to_string(camera.packet_size_bytes)};
  if (!aravis && camera.packet_size_bytes != 0)
    return ConfigIssue{at + "/packet_size", "only the aravis driver takes a packet_size"};
  if (camera.socket_buffer_bytes < 0)
    return ConfigIssue{at + "/socket_buffer", "expected auto or a byte count > 0, got " +
                                                  std::to_string(camera.socket_buffer_bytes)};
  if (!aravis && camera.socket_buffer_bytes != 0)
    return ConfigIssue{at + "/socket_buffer", "only the aravis driver takes a socket_buffer"};
  if (auto issue = CheckText(at + "/vicon_object", camera.vicon_object, false)) return issue;
  if (auto issue = CheckText(at + "/device_clock", camera.device_clock, false)) return issue;
  return std::nullopt;
}

std::optional<ConfigIssue> CheckCameras(const std::vector<CameraConfig>& cameras,
                                        const std::string& plate_object) {
  if (cameras.empty()) return ConfigIssue{"/cameras", "expected at least one camera"};
  std::map<std::string, std::size_t> serials, names, objects;
  int reference = -1;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const CameraConfig& camera = cameras[i];
    const std::string at = "/cameras/" + std::to_string(i);
    if (auto issue = CheckCamera(at, camera)) return issue;
    if (const auto [it, inserted] = serials.emplace(camera.serial, i); !inserted)
      return ConfigIssue{at + "/serial", "serial " + Quoted(camera.serial) +
                                             " is already used by /cameras/" +
                                             std::to_string(it->second)};
    if (const auto [it, inserted] = names.emplace(camera.name, i); !inserted)
      return ConfigIssue{at + "/name", "name " + Quoted(camera.name) +
                                           " is already used by /cameras/" +
                                           std::to_string(it->second)};
    if (!camera.vicon_object.empty()) {
      if (camera.vicon_object == plate_object)
        return ConfigIssue{at + "/vicon_object",
                           Quoted(camera.vicon_object) + " is the Vicon plate_object"};
      if (const auto [it, inserted] = objects.emplace(camera.vicon_object, i); !inserted)
        return ConfigIssue{at + "/vicon_object", "Vicon object " + Quoted(camera.vicon_object) +
                                                     " is already used by /cameras/" +
                                                     std::to_string(it->second)};
    }
    if (camera.role == CameraRole::kReference) {
      if (reference >= 0)
        return ConfigIssue{at + "/role",
                           "expected exactly one camera with role reference, found a second one "
                           "(the first is /cameras/" +
                               std::to_string(reference) + ")"};
      reference = static_cast<int>(i);
    }
  }
  if (reference < 0)
    return ConfigIssue{"/cameras", "expected exactly one camera with role reference, found none"};
  return std::nullopt;
}

std::optional<ConfigIssue> CheckVicon(const ViconConfig& vicon) {
  if (!IsIpv4(vicon.udp.address))
    return ConfigIssue{"/vicon/udp/address", "expected an IPv4 address such as 0.0.0.0, got " +
                                                 Quoted(vicon.udp.address)};
  if (vicon.udp.port < 1 || vicon.udp.port > 65535)
    return ConfigIssue{"/vicon/udp/port",
                       "expected a port in 1..65535, got " + std::to_string(vicon.udp.port)};
  if (vicon.source == ViconSourceKind::kCsv && vicon.csv.empty())
    return ConfigIssue{"/vicon/csv", "expected the path of the Vicon CSV for source csv"};
  if (auto issue = CheckText("/vicon/plate_object", vicon.plate_object, true)) return issue;
  // Vicon systems run at tens to thousands of Hz; below 1 Hz the trigger
  // period (in ns, drivers/camera_factory.h) leaves any real timing.
  if (!std::isfinite(vicon.rate_hz) || vicon.rate_hz < kMinViconRateHz ||
      vicon.rate_hz > 10000.0)
    return ConfigIssue{"/vicon/rate_hz",
                       "expected a number 1 .. 10000 (Hz), got " + NumberText(vicon.rate_hz)};
  if (vicon.trigger_divider < 1 || vicon.trigger_divider > 10000)
    return ConfigIssue{"/vicon/trigger_divider",
                       "expected an integer 1 .. 10000, got " + std::to_string(vicon.trigger_divider)};
  // The cameras' trigger period: more than a minute between two frames is a
  // typo (rate_hz 0.08 for 80, a divider of 8000 for 8), not a rig.
  if (vicon.trigger_divider / vicon.rate_hz > kMaxTriggerPeriodS)
    return ConfigIssue{"/vicon/trigger_divider",
                       "gives camera triggers every " +
                           NumberText(vicon.trigger_divider / vicon.rate_hz) + " s (rate_hz " +
                           NumberText(vicon.rate_hz) + " / trigger_divider " +
                           std::to_string(vicon.trigger_divider) +
                           "); expected a trigger at least every " +
                           NumberText(kMaxTriggerPeriodS) + " s"};
  return std::nullopt;
}

std::optional<ConfigIssue> CheckRecorder(const RecorderConfig& recorder) {
  if (recorder.queue_frames < 1 || recorder.queue_frames > 4096)
    return ConfigIssue{"/recorder/queue_frames",
                       "expected 1..4096 frames, got " + std::to_string(recorder.queue_frames)};
  if (recorder.writer_threads < 1 || recorder.writer_threads > 64)
    return ConfigIssue{"/recorder/writer_threads",
                       "expected 1..64 threads, got " + std::to_string(recorder.writer_threads)};
  if (recorder.direct_io_min_kb < 0 || recorder.direct_io_min_kb > (1 << 22))
    return ConfigIssue{"/recorder/direct_io_min_kb",
                       "expected 0..4194304 KiB (0: O_DIRECT for every frame), got " +
                           std::to_string(recorder.direct_io_min_kb)};
  if (recorder.max_memory_mb < 0)
    return ConfigIssue{"/recorder/max_memory_mb", "expected 0 (no cap) or a size in MiB > 0, got " +
                                                      std::to_string(recorder.max_memory_mb)};
  return std::nullopt;
}

std::optional<ConfigIssue> CheckProcessing(const ProcessingConfig& processing) {
  if (processing.threads < 0 || processing.threads > 1024)
    return ConfigIssue{"/processing/threads", "expected 0 (all cores) or 1..1024 threads, got " +
                                                  std::to_string(processing.threads)};
  if (processing.preview_max_px < 16 || processing.preview_max_px > 8192)
    return ConfigIssue{"/processing/preview_max_px", "expected 16..8192 pixels, got " +
                                                         std::to_string(processing.preview_max_px)};
  return std::nullopt;
}

std::optional<ConfigIssue> CheckLcm(const LcmConfig& lcm) {
  if (const std::optional<std::string> problem = LcmUrlProblem(lcm.url))
    return ConfigIssue{"/lcm/url", *problem};
  bool prefix_ok = !lcm.channel_prefix.empty();
  for (const char c : lcm.channel_prefix)
    prefix_ok = prefix_ok && ((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_');
  if (!prefix_ok)
    return ConfigIssue{"/lcm/channel_prefix",
                       "expected UPPER_SNAKE_CASE ([A-Z0-9_]+), got " + Quoted(lcm.channel_prefix)};
  return std::nullopt;
}

// ---------------------------------------------------------------- reading

fs::path Resolve(const fs::path& base_dir, const std::string& text) {
  const fs::path path(text);
  return (path.is_absolute() ? path : base_dir / path).lexically_normal();
}

void ReadPath(YamlMap& map, std::string_view key, const fs::path& base_dir, fs::path* out,
              Presence presence) {
  std::string text;
  const std::optional<YamlNode> value = map.Child(key, presence);
  if (!value) return;
  map.Read(key, &text, presence);
  if (!map.ok()) return;
  if (text.empty()) {
    map.Fail(*value, "expected a path, got an empty string");
    return;
  }
  *out = Resolve(base_dir, text);
}

// "auto" or a byte count > 0; auto is stored as 0.
void ReadSocketBuffer(YamlMap& map, std::int64_t* out) {
  const std::optional<YamlNode> value = map.Child("socket_buffer", Presence::kOptional);
  if (!value || !map.ok()) return;
  const std::string& text = value->Scalar();
  std::int64_t bytes = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), bytes);
  if (value->IsScalar() && !value->IsQuoted() && text == "auto") {
    *out = 0;
  } else if (value->IsScalar() && !value->IsQuoted() && !text.empty() && ec == std::errc() &&
             end == text.data() + text.size() && bytes > 0) {
    *out = bytes;
  } else {
    map.Fail(*value, "expected auto or a byte count > 0, got " + value->Describe());
  }
}

CameraConfig ReadCamera(const YamlNode& node, const fs::path& base_dir, YamlErrors* errors) {
  CameraConfig camera;
  YamlMap map(node, errors);
  if (!map.ok()) return camera;
  constexpr Presence kRequired = Presence::kRequired;
  constexpr Presence kOptional = Presence::kOptional;
  map.Read("serial", &camera.serial, kRequired);
  map.Read("name", &camera.name, kRequired);
  map.ReadEnum("role", &camera.role, ParseCameraRole, CameraRoleNames(), kRequired);
  if (auto driver = map.Map("driver", kRequired)) {
    driver->ReadEnum("kind", &camera.driver.kind, ParseDriverKind, DriverKindNames(), kRequired);
    driver->Read("address", &camera.driver.address, kOptional);
    ReadPath(*driver, "cti", base_dir, &camera.driver.cti, kOptional);
    driver->Read("interface", &camera.driver.interface_id, kOptional);
    driver->Read("device", &camera.driver.device, kOptional);
    driver->Read("loop", &camera.driver.loop, kOptional);
    driver->Finish();
  }
  ReadPath(map, "mla_file", base_dir, &camera.mla_file, kRequired);
  if (auto trigger = map.Map("trigger", kOptional)) {
    trigger->ReadEnum("mode", &camera.trigger.mode, ParseTriggerMode, TriggerModeNames(),
                      kOptional);
    trigger->Read("source", &camera.trigger.source, kOptional);
    trigger->ReadEnum("activation", &camera.trigger.activation, ParseTriggerActivation,
                      TriggerActivationNames(), kOptional);
    trigger->Finish();
  }
  map.Read("exposure_us", &camera.exposure_us, kOptional);
  map.Read("gain_db", &camera.gain_db, kOptional);
  map.ReadEnum("pixel_format", &camera.pixel_format, ParseCameraPixelFormat,
               CameraPixelFormatNames(), kOptional);
  if (auto roi_map = map.Map("roi", kOptional)) {
    RoiConfig roi;
    roi_map->Read("x", &roi.x_px, kOptional);
    roi_map->Read("y", &roi.y_px, kOptional);
    roi_map->Read("width", &roi.width_px, kRequired);
    roi_map->Read("height", &roi.height_px, kRequired);
    roi_map->Finish();
    camera.roi = roi;
  }
  map.Read("packet_size", &camera.packet_size_bytes, kOptional);
  ReadSocketBuffer(map, &camera.socket_buffer_bytes);
  map.Read("vicon_object", &camera.vicon_object, kOptional);
  map.Read("device_clock", &camera.device_clock, kOptional);
  map.Finish();
  return camera;
}

void ReadVicon(YamlMap& map, const fs::path& base_dir, ViconConfig* vicon) {
  constexpr Presence kOptional = Presence::kOptional;
  map.ReadEnum("source", &vicon->source, ParseViconSource, ViconSourceNames(), kOptional);
  if (auto udp = map.Map("udp", kOptional)) {
    udp->Read("address", &vicon->udp.address, kOptional);
    udp->Read("port", &vicon->udp.port, kOptional);
    udp->Finish();
  }
  ReadPath(map, "csv", base_dir, &vicon->csv, kOptional);
  map.ReadEnum("rotation", &vicon->rotation, ParseRotationRepresentation,
               RotationRepresentationNames(), kOptional);
  map.ReadEnum("handedness", &vicon->handedness, ParseHandedness, HandednessNames(), kOptional);
  map.Read("plate_object", &vicon->plate_object, kOptional);
  map.Read("rate_hz", &vicon->rate_hz, kOptional);
  map.Read("trigger_divider", &vicon->trigger_divider, kOptional);
  ReadPath(map, "vsk", base_dir, &vicon->vsk, kOptional);
  map.Finish();
}

// The files the pipeline reads must exist; the .cti is the driver's business.
std::optional<ConfigIssue> CheckFiles(const RigConfig& rig) {
  // What is there instead ("no such file or folder", "is a folder", "a
  // symbolic link loop", ...; config/input_file.h), empty for a regular file.
  const auto missing = [](const fs::path& path) { return DescribeNonRegular(path); };
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const fs::path& file = rig.cameras[i].mla_file;
    if (const std::string why = missing(file); !why.empty())
      return ConfigIssue{"/cameras/" + std::to_string(i) + "/mla_file",
                         "expected an existing MLA calibration file: " + EscapeText(file.string()) +
                             ": " + why};
  }
  if (!rig.vicon.csv.empty())
    if (const std::string why = missing(rig.vicon.csv); !why.empty())
      return ConfigIssue{"/vicon/csv", "expected an existing Vicon CSV file: " +
                                           EscapeText(rig.vicon.csv.string()) + ": " + why};
  if (!rig.vicon.vsk.empty())
    if (const std::string why = missing(rig.vicon.vsk); !why.empty())
      return ConfigIssue{"/vicon/vsk", "expected an existing VSK file: " +
                                           EscapeText(rig.vicon.vsk.string()) + ": " + why};
  return std::nullopt;
}

// ---------------------------------------------------------------- writing

// YAML double-quoted scalar; Check() keeps control characters out of the
// fields, but escaping them too keeps any RigConfig writable.
std::string Yq(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (byte < 0x20 || byte == 0x7f) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string Yb(bool value) { return value ? "true" : "false"; }

}  // namespace

// The URL forms of LCM's providers (lcm_create): udpm://[GROUP[:PORT]][?ttl=N&
// recv_buf_size=BYTES&transmit_only=BOOL], memq://, file://PATH[?mode=r|w|a&
// speed=X&start_timestamp=US], tcpq://[HOST[:PORT]]. LCM itself reports a bad
// URL only when the publisher starts (lcm_create returns NULL, or warns and
// ignores an unknown option), so a rig file is checked here, at its line.
std::optional<std::string> LcmUrlProblem(std::string_view url) {
  const std::string expected =
      "expected an LCM URL: udpm://GROUP:PORT?ttl=N (GROUP a multicast address "
      "224.0.0.0 .. 239.255.255.255), memq://, file://PATH?mode=r|w|a or tcpq://HOST:PORT";
  const std::string got = ", got " + Quoted(std::string(url));
  if (HasControlCharacter(std::string(url))) return expected + got;
  const std::size_t scheme_end = url.find("://");
  if (scheme_end == std::string_view::npos) return expected + got;
  const std::string_view provider = url.substr(0, scheme_end);
  const std::string_view rest = url.substr(scheme_end + 3);
  const std::size_t query = rest.find('?');
  const std::string_view network = rest.substr(0, query);
  const std::string_view options = query == std::string_view::npos ? "" : rest.substr(query + 1);
  // Options: key=value pairs joined by '&', each key known to the provider.
  std::vector<std::pair<std::string_view, std::string_view>> pairs;
  for (std::size_t start = 0; query != std::string_view::npos && start <= options.size();) {
    const std::size_t end = std::min(options.find('&', start), options.size());
    const std::string_view pair = options.substr(start, end - start);
    const std::size_t equals = pair.find('=');
    if (equals == std::string_view::npos || equals == 0)
      return "option " + Quoted(std::string(pair)) + " is not KEY=VALUE; " + expected + got;
    pairs.emplace_back(pair.substr(0, equals), pair.substr(equals + 1));
    start = end + 1;
  }
  const auto bad_option = [&](std::string_view key, std::string_view what) {
    return "option " + Quoted(std::string(key)) + " of " + std::string(provider) + "://: " +
           std::string(what) + got;
  };
  if (provider == "udpm") {
    if (!network.empty()) {
      const std::size_t colon = network.find(':');
      const std::string group(network.substr(0, colon));
      in_addr address{};
      if (inet_pton(AF_INET, group.c_str(), &address) != 1 ||
          (ntohl(address.s_addr) >> 28) != 0xE)
        return "udpm:// group " + Quoted(group) +
               " is not a multicast IPv4 address (224.0.0.0 .. 239.255.255.255)" + got;
      if (colon != std::string_view::npos && !IsPortText(network.substr(colon + 1)))
        return "udpm:// port " + Quoted(std::string(network.substr(colon + 1))) +
               " is not a port 1..65535" + got;
    }
    for (const auto& [key, value] : pairs) {
      if (key == "ttl") {
        if (!IsIntegerIn(value, 0, 255)) return bad_option(key, "expected 0..255");
      } else if (key == "recv_buf_size") {
        if (!IsIntegerIn(value, 1, 1LL << 31)) return bad_option(key, "expected bytes > 0");
      } else if (key == "transmit_only") {
        if (value != "true" && value != "false") return bad_option(key, "expected true or false");
      } else {
        return bad_option(key, "unknown (udpm:// takes ttl, recv_buf_size, transmit_only)");
      }
    }
    return std::nullopt;
  }
  if (provider == "memq") {
    if (!rest.empty()) return "memq:// takes no address or options" + got;
    return std::nullopt;
  }
  if (provider == "tcpq") {
    if (!network.empty()) {
      const std::size_t colon = network.find(':');
      const std::string_view host = network.substr(0, colon);
      if (host.empty() ||
          host.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789.-") !=
              std::string_view::npos)
        return "tcpq:// host " + Quoted(std::string(host)) +
               " is not a host name or IPv4 address" + got;
      if (colon != std::string_view::npos && !IsPortText(network.substr(colon + 1)))
        return "tcpq:// port " + Quoted(std::string(network.substr(colon + 1))) +
               " is not a port 1..65535" + got;
    }
    if (query != std::string_view::npos) return "tcpq:// takes no options" + got;
    return std::nullopt;
  }
  if (provider == "file") {
    if (network.empty()) return "file:// names no log file" + got;
    for (const auto& [key, value] : pairs) {
      if (key == "mode") {
        if (value != "r" && value != "w" && value != "a") return bad_option(key, "expected r, w or a");
      } else if (key == "speed") {
        double speed = 0;
        const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), speed);
        if (value.empty() || ec != std::errc() || end != value.data() + value.size() ||
            !std::isfinite(speed) || speed < 0)
          return bad_option(key, "expected a number >= 0");
      } else if (key == "start_timestamp") {
        if (!IsIntegerIn(value, 0, 999999999999999999LL))
          return bad_option(key, "expected microseconds >= 0");
      } else {
        return bad_option(key, "unknown (file:// takes mode, speed, start_timestamp)");
      }
    }
    return std::nullopt;
  }
  return expected + got;
}

std::optional<CameraRole> ParseCameraRole(std::string_view name) { return kRoleNames.Parse(name); }
std::string_view ToString(CameraRole value) { return kRoleNames.Name(value); }
std::string CameraRoleNames() { return kRoleNames.All(); }
std::optional<DriverKind> ParseDriverKind(std::string_view name) {
  return kDriverNames.Parse(name);
}
std::string_view ToString(DriverKind value) { return kDriverNames.Name(value); }
std::string DriverKindNames() { return kDriverNames.All(); }
std::optional<TriggerMode> ParseTriggerMode(std::string_view name) {
  return kTriggerModeNames.Parse(name);
}
std::string_view ToString(TriggerMode value) { return kTriggerModeNames.Name(value); }
std::string TriggerModeNames() { return kTriggerModeNames.All(); }
std::optional<TriggerActivation> ParseTriggerActivation(std::string_view name) {
  return kActivationNames.Parse(name);
}
std::string_view ToString(TriggerActivation value) { return kActivationNames.Name(value); }
std::string TriggerActivationNames() { return kActivationNames.All(); }
std::optional<CameraPixelFormat> ParseCameraPixelFormat(std::string_view name) {
  return kPixelFormatNames.Parse(name);
}
std::string_view ToString(CameraPixelFormat value) { return kPixelFormatNames.Name(value); }
std::string CameraPixelFormatNames() { return kPixelFormatNames.All(); }
std::optional<ViconSourceKind> ParseViconSource(std::string_view name) {
  return kViconSourceNames.Parse(name);
}
std::string_view ToString(ViconSourceKind value) { return kViconSourceNames.Name(value); }
std::string ViconSourceNames() { return kViconSourceNames.All(); }
std::optional<SkipPolicy> ParseSkipPolicy(std::string_view name) {
  return kSkipPolicyNames.Parse(name);
}
std::string_view ToString(SkipPolicy value) { return kSkipPolicyNames.Name(value); }
std::string SkipPolicyNames() { return kSkipPolicyNames.All(); }

PixelFormat BufferPixelFormat(CameraPixelFormat format) {
  return format == CameraPixelFormat::kBgr8 ? PixelFormat::kBgr8 : PixelFormat::kMono8;
}

std::optional<ConfigIssue> RigConfig::FindIssue() const {
  if (auto issue = CheckText("/rig/name", name, true)) return issue;
  if (auto issue = CheckCameras(cameras, vicon.plate_object)) return issue;
  if (auto issue = CheckVicon(vicon)) return issue;
  if (auto issue = CheckRecorder(recorder)) return issue;
  if (auto issue = CheckProcessing(processing)) return issue;
  if (auto issue = CheckLcm(lcm)) return issue;
  if (registration.changed_after < 1 || registration.changed_after > 100)
    return ConfigIssue{"/registration/changed_after",
                       "expected 1..100, got " + std::to_string(registration.changed_after)};
  if (registration.settle_triggers < 2 || registration.settle_triggers > 1000)
    return ConfigIssue{"/registration/settle_triggers",
                       "expected 2..1000, got " + std::to_string(registration.settle_triggers)};
  return std::nullopt;
}

Status RigConfig::Check() const {
  if (const auto issue = FindIssue())
    return MakeErrorAt("rig '" + name + "'", issue->path, issue->what);
  return Status::Ok();
}

int RigConfig::ReferenceIndex() const {
  for (std::size_t i = 0; i < cameras.size(); ++i)
    if (cameras[i].role == CameraRole::kReference) return static_cast<int>(i);
  return -1;
}

Expected<RigConfig> ParseRigConfig(std::string_view yaml, const fs::path& base_dir,
                                   const std::string& label) {
  Expected<YamlNode> parsed = YamlNode::Parse(yaml, label);
  if (!parsed) return parsed.error();
  const YamlNode& root_node = *parsed;
  constexpr Presence kRequired = Presence::kRequired;
  constexpr Presence kOptional = Presence::kOptional;

  RigConfig rig;
  YamlErrors errors;
  YamlMap root(root_node, &errors);
  if (auto section = root.Map("rig", kRequired)) {
    section->Read("name", &rig.name, kRequired);
    section->Finish();
  }
  if (auto cameras = root.List("cameras", kRequired)) {
    for (const YamlNode& camera : *cameras) {
      if (!errors.ok()) break;
      rig.cameras.push_back(ReadCamera(camera, base_dir, &errors));
    }
  }
  if (auto section = root.Map("vicon", kOptional)) ReadVicon(*section, base_dir, &rig.vicon);
  if (auto section = root.Map("recorder", kOptional)) {
    ReadPath(*section, "out_dir", base_dir, &rig.recorder.out_dir, kOptional);
    section->Read("queue_frames", &rig.recorder.queue_frames, kOptional);
    section->Read("writer_threads", &rig.recorder.writer_threads, kOptional);
    section->Read("direct_io", &rig.recorder.direct_io, kOptional);
    section->Read("direct_io_min_kb", &rig.recorder.direct_io_min_kb, kOptional);
    section->Read("max_memory_mb", &rig.recorder.max_memory_mb, kOptional);
    section->Finish();
  }
  if (auto section = root.Map("processing", kOptional)) {
    section->Read("enabled", &rig.processing.enabled, kOptional);
    section->Read("threads", &rig.processing.threads, kOptional);
    section->ReadEnum("skip_policy", &rig.processing.skip_policy, ParseSkipPolicy,
                      SkipPolicyNames(), kOptional);
    section->Read("preview_max_px", &rig.processing.preview_max_px, kOptional);
    section->Finish();
  }
  if (auto section = root.Map("lcm", kOptional)) {
    section->Read("url", &rig.lcm.url, kOptional);
    section->Read("channel_prefix", &rig.lcm.channel_prefix, kOptional);
    section->Read("publish_previews", &rig.lcm.publish_previews, kOptional);
    section->Finish();
  }
  if (auto section = root.Map("registration", kOptional)) {
    section->Read("rigid_mount", &rig.registration.rigid_mount, kOptional);
    section->Read("changed_after", &rig.registration.changed_after, kOptional);
    section->Read("settle_triggers", &rig.registration.settle_triggers, kOptional);
    section->Finish();
  }
  root.Finish();
  if (!errors.ok()) return errors.status().error();

  if (const auto issue = rig.FindIssue()) return root_node.ErrorAtPath(issue->path, issue->what);
  if (const auto issue = CheckFiles(rig)) return root_node.ErrorAtPath(issue->path, issue->what);
  return rig;
}

Expected<RigConfig> LoadRigConfig(const fs::path& path) {
  Expected<std::string> text = ReadInputText(path, {"a rig file (YAML)", kRigFileMaxBytes});
  if (!text) return text.error();
  return ParseRigConfig(*text, fs::absolute(path).parent_path(), EscapeText(path.string()));
}

std::string FormatRigConfig(const RigConfig& rig) {
  std::ostringstream out;
  out << "# lifmcr rig configuration (every field is described in config/README.md)\n";
  out << "rig:\n  name: " << Yq(rig.name) << "\n";
  out << (rig.cameras.empty() ? "cameras: []\n" : "cameras:\n");
  for (const CameraConfig& camera : rig.cameras) {
    out << "  - serial: " << Yq(camera.serial) << "\n";
    out << "    name: " << Yq(camera.name) << "\n";
    out << "    role: " << ToString(camera.role) << "\n";
    out << "    driver:\n      kind: " << ToString(camera.driver.kind) << "\n";
    if (!camera.driver.address.empty())
      out << "      address: " << Yq(camera.driver.address) << "\n";
    if (!camera.driver.cti.empty()) out << "      cti: " << Yq(camera.driver.cti.string()) << "\n";
    if (!camera.driver.interface_id.empty())
      out << "      interface: " << Yq(camera.driver.interface_id) << "\n";
    if (!camera.driver.device.empty())
      out << "      device: " << Yq(camera.driver.device) << "\n";
    if (camera.driver.loop) out << "      loop: true\n";
    if (!camera.mla_file.empty()) out << "    mla_file: " << Yq(camera.mla_file.string()) << "\n";
    out << "    trigger:\n      mode: " << ToString(camera.trigger.mode) << "\n";
    out << "      source: " << Yq(camera.trigger.source) << "\n";
    out << "      activation: " << ToString(camera.trigger.activation) << "\n";
    out << "    exposure_us: " << NumberText(camera.exposure_us) << "\n";
    out << "    gain_db: " << NumberText(camera.gain_db) << "\n";
    out << "    pixel_format: " << ToString(camera.pixel_format) << "\n";
    if (camera.roi) {
      out << "    roi: {x: " << camera.roi->x_px << ", y: " << camera.roi->y_px
          << ", width: " << camera.roi->width_px << ", height: " << camera.roi->height_px << "}\n";
    }
    out << "    packet_size: " << camera.packet_size_bytes << "\n";
    out << "    socket_buffer: "
        << (camera.socket_buffer_bytes == 0 ? std::string("auto")
                                            : std::to_string(camera.socket_buffer_bytes))
        << "\n";
    out << "    vicon_object: " << Yq(camera.vicon_object) << "\n";
    if (!camera.device_clock.empty())
      out << "    device_clock: " << Yq(camera.device_clock) << "\n";
  }
  const ViconConfig& vicon = rig.vicon;
  out << "vicon:\n  source: " << ToString(vicon.source) << "\n";
  out << "  udp:\n    address: " << Yq(vicon.udp.address) << "\n    port: " << vicon.udp.port
      << "\n";
  if (!vicon.csv.empty()) out << "  csv: " << Yq(vicon.csv.string()) << "\n";
  out << "  rotation: " << ToString(vicon.rotation) << "\n";
  out << "  handedness: " << ToString(vicon.handedness) << "\n";
  out << "  plate_object: " << Yq(vicon.plate_object) << "\n";
  out << "  rate_hz: " << NumberText(vicon.rate_hz) << "\n";
  out << "  trigger_divider: " << vicon.trigger_divider << "\n";
  if (!vicon.vsk.empty()) out << "  vsk: " << Yq(vicon.vsk.string()) << "\n";
  const RecorderConfig& recorder = rig.recorder;
  out << "recorder:\n";
  if (!recorder.out_dir.empty()) out << "  out_dir: " << Yq(recorder.out_dir.string()) << "\n";
  out << "  queue_frames: " << recorder.queue_frames << "\n";
  out << "  writer_threads: " << recorder.writer_threads << "\n";
  out << "  direct_io: " << Yb(recorder.direct_io) << "\n";
  out << "  direct_io_min_kb: " << recorder.direct_io_min_kb << "\n";
  out << "  max_memory_mb: " << recorder.max_memory_mb << "\n";
  const ProcessingConfig& processing = rig.processing;
  out << "processing:\n  enabled: " << Yb(processing.enabled) << "\n";
  out << "  threads: " << processing.threads << "\n";
  out << "  skip_policy: " << ToString(processing.skip_policy) << "\n";
  out << "  preview_max_px: " << processing.preview_max_px << "\n";
  out << "lcm:\n  url: " << Yq(rig.lcm.url) << "\n";
  out << "  channel_prefix: " << Yq(rig.lcm.channel_prefix) << "\n";
  out << "  publish_previews: " << Yb(rig.lcm.publish_previews) << "\n";
  out << "registration:\n  rigid_mount: " << Yb(rig.registration.rigid_mount) << "\n";
  out << "  changed_after: " << rig.registration.changed_after << "\n";
  out << "  settle_triggers: " << rig.registration.settle_triggers << "\n";
  return out.str();
}

}  // namespace lifmcr
