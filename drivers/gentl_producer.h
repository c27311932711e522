#pragma once
// A GenTL producer (.cti) loaded into this process: the library, its entry
// points, and its system module (TLOpen), shared by every camera that uses it.
//
// Loading checks, in order, each failure a Status naming the file: the file
// exists; it is an ELF shared object of this process's class and machine (a
// 32-bit or ARM producer on an x86-64 host is refused before dlopen, whose
// own message would only say "wrong ELF class"); dlopen succeeds; every
// required entry point is exported (all missing names are listed); GCInitLib
// and TLOpen succeed. GCInitLib may be called once per process, so producers
// are cached by canonical path: a second Load of the same file returns the
// same object while anyone holds it.
//
// Failed calls are described as "<call> failed: GC_ERR_NAME (code): <the
// producer's GCGetLastError text>".
//
// Discovery (Devices) refreshes the interface and device lists and reads each
// device's id, vendor, model, serial, transport type and access status; it
// opens interfaces, which stay open for the producer's lifetime (the standard
// allows one open per interface). The producer's mutex serialises discovery
// and interface access between cameras.

#include "config/error.h"
#include "drivers/gentl_api.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace lifmcr {

struct GenTlDeviceEntry {
  std::string interface_id;
  std::string interface_name;  // display name of the interface
  std::string id;              // the device id IFOpenDevice takes
  std::string vendor;
  std::string model;
  std::string serial;
  std::string display_name;
  std::string tl_type;  // "CXP", "GEV", "U3V", ...
  gentl::DEVICE_ACCESS_STATUS access = gentl::DEVICE_ACCESS_STATUS_UNKNOWN;
};

struct GenTlInterfaceEntry {
  std::string id;
  std::string display_name;
  std::string tl_type;
};

struct GenTlProducerInfo {
  std::filesystem::path path;
  std::string vendor;
  std::string model;
  std::string version;
  std::string tl_type;
  std::string gentl_version;  // "1.5", or "" when the producer does not say
};

class GenTlProducer {
 public:
  static Expected<std::shared_ptr<GenTlProducer>> Load(const std::filesystem::path& cti);

  // The .cti files in the directories of GENICAM_GENTL64_PATH (':'-separated,
  // the standard's variable for 64-bit consumers), in order; empty when it is
  // unset.
  static std::vector<std::filesystem::path> SearchPath();

  ~GenTlProducer();
  GenTlProducer(const GenTlProducer&) = delete;
  GenTlProducer& operator=(const GenTlProducer&) = delete;

  const gentl::Functions& fn() const { return fn_; }
  gentl::TL_HANDLE system() const { return system_; }
  const std::filesystem::path& path() const { return path_; }
  GenTlProducerInfo Info() const;

  // "<call> failed: GC_ERR_IO (-1010): <GCGetLastError text>". Call it on the
  // thread that made the failed call, right after it.
  std::string Describe(gentl::GC_ERROR code, const std::string& call) const;

  // Interfaces after TLUpdateInterfaceList.
  Expected<std::vector<GenTlInterfaceEntry>> Interfaces(std::chrono::milliseconds timeout);
  // Devices of every interface, or of `interface_id` only, after
  // IFUpdateDeviceList on each.
  Expected<std::vector<GenTlDeviceEntry>> Devices(const std::string& interface_id,
                                                  std::chrono::milliseconds timeout);
  // The interface's handle, opened on first use.
  Expected<gentl::IF_HANDLE> Interface(const std::string& interface_id);

  std::mutex& mutex() { return mutex_; }

 private:
  GenTlProducer() = default;
  Expected<gentl::IF_HANDLE> InterfaceLocked(const std::string& interface_id);

  std::filesystem::path path_;
  void* library_ = nullptr;  // dlopen handle
  gentl::Functions fn_;
  bool initialised_ = false;
  gentl::TL_HANDLE system_ = nullptr;
  std::mutex mutex_;
  std::map<std::string, gentl::IF_HANDLE> interfaces_;
};

// What a producer exposes, for `lifmcr info --gentl` and rig files: its
// identity, interfaces and devices (with serials and access status).
struct GenTlListing {
  GenTlProducerInfo producer;
  std::vector<GenTlInterfaceEntry> interfaces;
  std::vector<GenTlDeviceEntry> devices;
};
Expected<GenTlListing> ListGenTlProducer(const std::filesystem::path& cti,
                                         std::chrono::milliseconds timeout);

// Text of a GenTL info value returned as a string (TLGetInfo, IFGetDeviceInfo,
// ...): `query(type, buffer, size)` is called to size and then to fill.
// Empty when the call fails.
template <typename Query>
std::string GenTlInfoString(Query query) {
  std::size_t size = 0;
  gentl::INFO_DATATYPE type = gentl::INFO_DATATYPE_UNKNOWN;
  if (query(&type, nullptr, &size) != gentl::GC_ERR_SUCCESS || size == 0) return {};
  std::string text(size, '\0');
  if (query(&type, text.data(), &size) != gentl::GC_ERR_SUCCESS) return {};
  text.resize(std::min(size, text.size()));
  while (!text.empty() && text.back() == '\0') text.pop_back();
  return text;
}

// A fixed-size GenTL info value (integers, pointers, BOOL8): false when the
// call fails.
template <typename T, typename Query>
bool GenTlInfoValue(Query query, T* value) {
  std::size_t size = sizeof(T);
  gentl::INFO_DATATYPE type = gentl::INFO_DATATYPE_UNKNOWN;
  return query(&type, value, &size) == gentl::GC_ERR_SUCCESS;
}

}  // namespace lifmcr
