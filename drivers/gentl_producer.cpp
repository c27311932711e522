#include "drivers/gentl_producer.h"

#include <dlfcn.h>
#include <elf.h>

#include <cstdlib>
#include <cstring>
#include <fstream>

namespace lifmcr {
namespace gentl {

std::string ErrorName(GC_ERROR code) {
  switch (code) {
    case GC_ERR_SUCCESS: return "GC_ERR_SUCCESS";
    case GC_ERR_ERROR: return "GC_ERR_ERROR";
    case GC_ERR_NOT_INITIALIZED: return "GC_ERR_NOT_INITIALIZED";
    case GC_ERR_NOT_IMPLEMENTED: return "GC_ERR_NOT_IMPLEMENTED";
    case GC_ERR_RESOURCE_IN_USE: return "GC_ERR_RESOURCE_IN_USE";
    case GC_ERR_ACCESS_DENIED: return "GC_ERR_ACCESS_DENIED";
    case GC_ERR_INVALID_HANDLE: return "GC_ERR_INVALID_HANDLE";
    case GC_ERR_INVALID_ID: return "GC_ERR_INVALID_ID";
    case GC_ERR_NO_DATA: return "GC_ERR_NO_DATA";
    case GC_ERR_INVALID_PARAMETER: return "GC_ERR_INVALID_PARAMETER";
    case GC_ERR_IO: return "GC_ERR_IO";
    case GC_ERR_TIMEOUT: return "GC_ERR_TIMEOUT";
    case GC_ERR_ABORT: return "GC_ERR_ABORT";
    case GC_ERR_INVALID_BUFFER: return "GC_ERR_INVALID_BUFFER";
    case GC_ERR_NOT_AVAILABLE: return "GC_ERR_NOT_AVAILABLE";
    case GC_ERR_INVALID_ADDRESS: return "GC_ERR_INVALID_ADDRESS";
    case GC_ERR_BUFFER_TOO_SMALL: return "GC_ERR_BUFFER_TOO_SMALL";
    case GC_ERR_INVALID_INDEX: return "GC_ERR_INVALID_INDEX";
    case GC_ERR_PARSING_CHUNK_DATA: return "GC_ERR_PARSING_CHUNK_DATA";
    case GC_ERR_INVALID_VALUE: return "GC_ERR_INVALID_VALUE";
    case GC_ERR_RESOURCE_EXHAUSTED: return "GC_ERR_RESOURCE_EXHAUSTED";
    case GC_ERR_OUT_OF_MEMORY: return "GC_ERR_OUT_OF_MEMORY";
    case GC_ERR_BUSY: return "GC_ERR_BUSY";
    default: break;
  }
  if (code <= GC_ERR_CUSTOM_ID) return "GC_ERR_CUSTOM_ID" + std::to_string(code - GC_ERR_CUSTOM_ID);
  return "GC_ERROR(" + std::to_string(code) + ")";
}

std::string_view AccessStatusName(DEVICE_ACCESS_STATUS status) {
  switch (status) {
    case DEVICE_ACCESS_STATUS_READWRITE: return "readwrite";
    case DEVICE_ACCESS_STATUS_READONLY: return "readonly";
    case DEVICE_ACCESS_STATUS_NOACCESS: return "no access";
    case DEVICE_ACCESS_STATUS_BUSY: return "busy (opened by another process or host)";
    case DEVICE_ACCESS_STATUS_OPEN_READWRITE: return "open (readwrite) in this process";
    case DEVICE_ACCESS_STATUS_OPEN_READONLY: return "open (readonly) in this process";
    default: return "unknown";
  }
}

}  // namespace gentl

namespace {

using namespace gentl;

std::mutex& CacheMutex() {
  static std::mutex mutex;
  return mutex;
}
std::map<std::string, std::weak_ptr<GenTlProducer>>& Cache() {
  static std::map<std::string, std::weak_ptr<GenTlProducer>> cache;
  return cache;
}

#if defined(__x86_64__)
constexpr int kHostMachine = EM_X86_64;
constexpr const char* kHostMachineName = "x86-64";
#elif defined(__aarch64__)
constexpr int kHostMachine = EM_AARCH64;
constexpr const char* kHostMachineName = "aarch64";
#else
constexpr int kHostMachine = -1;  // not checked
constexpr const char* kHostMachineName = "this host";
#endif

std::string MachineName(int machine) {
  switch (machine) {
    case EM_386: return "x86 (32-bit)";
    case EM_X86_64: return "x86-64";
    case EM_ARM: return "ARM (32-bit)";
    case EM_AARCH64: return "aarch64";
    case EM_PPC64: return "ppc64";
    case EM_RISCV: return "riscv";
    default: return "machine " + std::to_string(machine);
  }
}

// The ELF identification and machine of `path`, checked against this
// process; dlopen would refuse a mismatch with a less helpful message.
Status CheckElf(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  unsigned char header[EI_NIDENT + 4] = {};
  if (!file.read(reinterpret_cast<char*>(header), sizeof(header)))
    return Error{"GenTL producer " + path.string() + ": too short to be a shared library"};
  if (std::memcmp(header, ELFMAG, SELFMAG) != 0)
    return Error{"GenTL producer " + path.string() +
                 ": not an ELF shared library (a Windows .cti? producers are per platform)"};
  const int host_class = sizeof(void*) == 8 ? ELFCLASS64 : ELFCLASS32;
  if (header[EI_CLASS] != host_class)
    return Error{"GenTL producer " + path.string() + ": wrong architecture, a " +
                 (header[EI_CLASS] == ELFCLASS32 ? std::string("32-bit (ELFCLASS32)")
                                                 : std::string("64-bit (ELFCLASS64)")) +
                 " library in a " + std::to_string(8 * sizeof(void*)) +
                 "-bit process (use the vendor's 64-bit producer, GENICAM_GENTL64_PATH)"};
  const bool little = header[EI_DATA] == ELFDATA2LSB;
  const int machine = little ? header[EI_NIDENT + 2] | (header[EI_NIDENT + 3] << 8)
                             : (header[EI_NIDENT + 2] << 8) | header[EI_NIDENT + 3];
  if (kHostMachine >= 0 && machine != kHostMachine)
    return Error{"GenTL producer " + path.string() + ": wrong architecture, built for " +
                 MachineName(machine) + ", this host is " + kHostMachineName};
  return Status::Ok();
}

template <typename F>
void Resolve(void* library, const char* name, F* slot, std::vector<std::string>* missing) {
  void* symbol = dlsym(library, name);
  if (symbol == nullptr && missing != nullptr) missing->push_back(name);
  *slot = reinterpret_cast<F>(symbol);
}

}  // namespace

std::vector<std::filesystem::path> GenTlProducer::SearchPath() {
  std::vector<std::filesystem::path> found;
  const char* variable = std::getenv("GENICAM_GENTL64_PATH");
  if (variable == nullptr) return found;
  std::string list = variable;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t end = std::min(list.find(':', start), list.size());
    const std::filesystem::path dir = list.substr(start, end - start);
    start = end + 1;
    std::error_code error;
    if (dir.empty() || !std::filesystem::is_directory(dir, error)) continue;
    std::vector<std::filesystem::path> here;
    for (const auto& entry : std::filesystem::directory_iterator(dir, error))
      if (entry.path().extension() == ".cti") here.push_back(entry.path());
    std::sort(here.begin(), here.end());
    found.insert(found.end(), here.begin(), here.end());
  }
  return found;
}

Expected<std::shared_ptr<GenTlProducer>> GenTlProducer::Load(const std::filesystem::path& cti) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(cti, error))
    return Error{"GenTL producer " + cti.string() + ": no such file"};
  const std::filesystem::path canonical = std::filesystem::canonical(cti, error);
  const std::string key = error ? cti.string() : canonical.string();

  std::lock_guard<std::mutex> lock(CacheMutex());
  if (auto cached = Cache()[key].lock()) return cached;
  if (Status status = CheckElf(cti); !status) return status.error();

  std::shared_ptr<GenTlProducer> producer(new GenTlProducer());
  producer->path_ = key;
  // RTLD_LOCAL: two producers may export the same names.
  producer->library_ = dlopen(key.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (producer->library_ == nullptr) {
    const char* text = dlerror();
    return Error{"GenTL producer " + key + ": dlopen failed: " + (text ? text : "unknown error")};
  }
  std::vector<std::string> missing;
  Functions& fn = producer->fn_;
  void* lib = producer->library_;
  Resolve(lib, "GCGetInfo", &fn.GCGetInfo, &missing);
  Resolve(lib, "GCGetLastError", &fn.GCGetLastError, &missing);
  Resolve(lib, "GCInitLib", &fn.GCInitLib, &missing);
  Resolve(lib, "GCCloseLib", &fn.GCCloseLib, &missing);
  Resolve(lib, "GCReadPort", &fn.GCReadPort, &missing);
  Resolve(lib, "GCWritePort", &fn.GCWritePort, &missing);
  Resolve(lib, "GCGetPortURL", &fn.GCGetPortURL, &missing);
  Resolve(lib, "GCGetPortInfo", &fn.GCGetPortInfo, &missing);
  Resolve(lib, "GCRegisterEvent", &fn.GCRegisterEvent, &missing);
  Resolve(lib, "GCUnregisterEvent", &fn.GCUnregisterEvent, &missing);
  Resolve(lib, "EventGetData", &fn.EventGetData, &missing);
  Resolve(lib, "EventFlush", &fn.EventFlush, &missing);
  Resolve(lib, "EventKill", &fn.EventKill, &missing);
  Resolve(lib, "TLOpen", &fn.TLOpen, &missing);
  Resolve(lib, "TLClose", &fn.TLClose, &missing);
  Resolve(lib, "TLGetInfo", &fn.TLGetInfo, &missing);
  Resolve(lib, "TLGetNumInterfaces", &fn.TLGetNumInterfaces, &missing);
  Resolve(lib, "TLGetInterfaceID", &fn.TLGetInterfaceID, &missing);
  Resolve(lib, "TLGetInterfaceInfo", &fn.TLGetInterfaceInfo, &missing);
  Resolve(lib, "TLOpenInterface", &fn.TLOpenInterface, &missing);
  Resolve(lib, "TLUpdateInterfaceList", &fn.TLUpdateInterfaceList, &missing);
  Resolve(lib, "IFClose", &fn.IFClose, &missing);
  Resolve(lib, "IFGetInfo", &fn.IFGetInfo, &missing);
  Resolve(lib, "IFGetNumDevices", &fn.IFGetNumDevices, &missing);
  Resolve(lib, "IFGetDeviceID", &fn.IFGetDeviceID, &missing);
  Resolve(lib, "IFUpdateDeviceList", &fn.IFUpdateDeviceList, &missing);
  Resolve(lib, "IFGetDeviceInfo", &fn.IFGetDeviceInfo, &missing);
  Resolve(lib, "IFOpenDevice", &fn.IFOpenDevice, &missing);
  Resolve(lib, "DevGetPort", &fn.DevGetPort, &missing);
  Resolve(lib, "DevGetNumDataStreams", &fn.DevGetNumDataStreams, &missing);
  Resolve(lib, "DevGetDataStreamID", &fn.DevGetDataStreamID, &missing);
  Resolve(lib, "DevOpenDataStream", &fn.DevOpenDataStream, &missing);
  Resolve(lib, "DevGetInfo", &fn.DevGetInfo, &missing);
  Resolve(lib, "DevClose", &fn.DevClose, &missing);
  Resolve(lib, "DSAnnounceBuffer", &fn.DSAnnounceBuffer, &missing);
  Resolve(lib, "DSFlushQueue", &fn.DSFlushQueue, &missing);
  Resolve(lib, "DSStartAcquisition", &fn.DSStartAcquisition, &missing);
  Resolve(lib, "DSStopAcquisition", &fn.DSStopAcquisition, &missing);
  Resolve(lib, "DSGetInfo", &fn.DSGetInfo, &missing);
  Resolve(lib, "DSClose", &fn.DSClose, &missing);
  Resolve(lib, "DSRevokeBuffer", &fn.DSRevokeBuffer, &missing);
  Resolve(lib, "DSQueueBuffer", &fn.DSQueueBuffer, &missing);
  Resolve(lib, "DSGetBufferInfo", &fn.DSGetBufferInfo, &missing);
  Resolve(lib, "GCGetNumPortURLs", &fn.GCGetNumPortURLs, nullptr);
  Resolve(lib, "GCGetPortURLInfo", &fn.GCGetPortURLInfo, nullptr);
  Resolve(lib, "DSGetBufferChunkData", &fn.DSGetBufferChunkData, nullptr);
  if (!missing.empty()) {
    std::string names;
    for (const std::string& name : missing) names += (names.empty() ? "" : ", ") + name;
    return Error{"GenTL producer " + key + ": not a GenTL producer, missing symbol" +
                 (missing.size() > 1 ? "s " : " ") + names};
  }
  if (GC_ERROR code = fn.GCInitLib(); code != GC_ERR_SUCCESS)
    return Error{"GenTL producer " + key + ": " + producer->Describe(code, "GCInitLib")};
  producer->initialised_ = true;
  if (GC_ERROR code = fn.TLOpen(&producer->system_); code != GC_ERR_SUCCESS)
    return Error{"GenTL producer " + key + ": " + producer->Describe(code, "TLOpen")};
  Cache()[key] = producer;
  return producer;
}

GenTlProducer::~GenTlProducer() {
  for (auto& [id, handle] : interfaces_) fn_.IFClose(handle);
  if (system_ != nullptr) fn_.TLClose(system_);
  if (initialised_) fn_.GCCloseLib();
  if (library_ != nullptr) dlclose(library_);
}

std::string GenTlProducer::Describe(GC_ERROR code, const std::string& call) const {
  std::string text = call + " failed: " + ErrorName(code) + " (" + std::to_string(code) + ")";
  if (fn_.GCGetLastError == nullptr) return text;
  GC_ERROR last = GC_ERR_SUCCESS;
  char message[512] = {};
  std::size_t size = sizeof(message);
  if (fn_.GCGetLastError(&last, message, &size) == GC_ERR_SUCCESS && message[0] != '\0') {
    message[sizeof(message) - 1] = '\0';
    text += ": ";
    text += message;
  }
  return text;
}

GenTlProducerInfo GenTlProducer::Info() const {
  GenTlProducerInfo info;
  info.path = path_;
  auto text = [this](TL_INFO_CMD command) {
    return GenTlInfoString([&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
      return fn_.TLGetInfo(system_, command, type, buffer, size);
    });
  };
  info.vendor = text(TL_INFO_VENDOR);
  info.model = text(TL_INFO_MODEL);
  info.version = text(TL_INFO_VERSION);
  info.tl_type = text(TL_INFO_TLTYPE);
  std::uint32_t major = 0, minor = 0;
  auto number = [this](TL_INFO_CMD command, std::uint32_t* value) {
    return GenTlInfoValue(
        [&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
          return fn_.TLGetInfo(system_, command, type, buffer, size);
        },
        value);
  };
  if (number(TL_INFO_GENTL_VER_MAJOR, &major) && number(TL_INFO_GENTL_VER_MINOR, &minor))
    info.gentl_version = std::to_string(major) + "." + std::to_string(minor);
  return info;
}

Expected<std::vector<GenTlInterfaceEntry>> GenTlProducer::Interfaces(
    std::chrono::milliseconds timeout) {
  std::lock_guard<std::mutex> lock(mutex_);
  bool8_t changed = 0;
  if (GC_ERROR code = fn_.TLUpdateInterfaceList(system_, &changed, timeout.count());
      code != GC_ERR_SUCCESS)
    return Error{"GenTL producer " + path_.string() + ": " +
                 Describe(code, "TLUpdateInterfaceList")};
  std::uint32_t count = 0;
  if (GC_ERROR code = fn_.TLGetNumInterfaces(system_, &count); code != GC_ERR_SUCCESS)
    return Error{"GenTL producer " + path_.string() + ": " + Describe(code, "TLGetNumInterfaces")};
  std::vector<GenTlInterfaceEntry> entries;
  for (std::uint32_t i = 0; i < count; ++i) {
    GenTlInterfaceEntry entry;
    entry.id = GenTlInfoString([&](INFO_DATATYPE*, void* buffer, std::size_t* size) {
      return fn_.TLGetInterfaceID(system_, i, static_cast<char*>(buffer), size);
    });
    if (entry.id.empty()) continue;
    auto text = [&](INTERFACE_INFO_CMD command) {
      return GenTlInfoString([&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
        return fn_.TLGetInterfaceInfo(system_, entry.id.c_str(), command, type, buffer, size);
      });
    };
    entry.display_name = text(INTERFACE_INFO_DISPLAYNAME);
    entry.tl_type = text(INTERFACE_INFO_TLTYPE);
    entries.push_back(std::move(entry));
  }
  return entries;
}

Expected<IF_HANDLE> GenTlProducer::Interface(const std::string& interface_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  return InterfaceLocked(interface_id);
}

Expected<IF_HANDLE> GenTlProducer::InterfaceLocked(const std::string& interface_id) {
  if (auto found = interfaces_.find(interface_id); found != interfaces_.end())
    return found->second;
  IF_HANDLE handle = nullptr;
  if (GC_ERROR code = fn_.TLOpenInterface(system_, interface_id.c_str(), &handle);
      code != GC_ERR_SUCCESS)
    return Error{"GenTL producer " + path_.string() + ": interface " + interface_id + ": " +
                 Describe(code, "TLOpenInterface")};
  interfaces_[interface_id] = handle;
  return handle;
}

Expected<std::vector<GenTlDeviceEntry>> GenTlProducer::Devices(const std::string& interface_id,
                                                               std::chrono::milliseconds timeout) {
  auto interfaces = Interfaces(timeout);
  if (!interfaces) return interfaces.error();
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<GenTlDeviceEntry> devices;
  bool interface_found = interface_id.empty();
  for (const GenTlInterfaceEntry& interface : *interfaces) {
    if (!interface_id.empty() && interface.id != interface_id) continue;
    interface_found = true;
    auto handle = InterfaceLocked(interface.id);
    if (!handle) return handle.error();
    bool8_t changed = 0;
    if (GC_ERROR code = fn_.IFUpdateDeviceList(*handle, &changed, timeout.count());
        code != GC_ERR_SUCCESS)
      return Error{"GenTL producer " + path_.string() + ": interface " + interface.id + ": " +
                   Describe(code, "IFUpdateDeviceList")};
    std::uint32_t count = 0;
    if (GC_ERROR code = fn_.IFGetNumDevices(*handle, &count); code != GC_ERR_SUCCESS)
      return Error{"GenTL producer " + path_.string() + ": interface " + interface.id + ": " +
                   Describe(code, "IFGetNumDevices")};
    for (std::uint32_t i = 0; i < count; ++i) {
      GenTlDeviceEntry entry;
      entry.interface_id = interface.id;
      entry.interface_name = interface.display_name;
      entry.id = GenTlInfoString([&](INFO_DATATYPE*, void* buffer, std::size_t* size) {
        return fn_.IFGetDeviceID(*handle, i, static_cast<char*>(buffer), size);
      });
      if (entry.id.empty()) continue;
      auto query = [&](DEVICE_INFO_CMD command) {
        return [&, command](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
          return fn_.IFGetDeviceInfo(*handle, entry.id.c_str(), command, type, buffer, size);
        };
      };
      entry.vendor = GenTlInfoString(query(DEVICE_INFO_VENDOR));
      entry.model = GenTlInfoString(query(DEVICE_INFO_MODEL));
      entry.serial = GenTlInfoString(query(DEVICE_INFO_SERIAL_NUMBER));
      entry.display_name = GenTlInfoString(query(DEVICE_INFO_DISPLAYNAME));
      entry.tl_type = GenTlInfoString(query(DEVICE_INFO_TLTYPE));
      if (!GenTlInfoValue(query(DEVICE_INFO_ACCESS_STATUS), &entry.access))
        entry.access = DEVICE_ACCESS_STATUS_UNKNOWN;
      devices.push_back(std::move(entry));
    }
  }
  if (!interface_found) {
    std::string ids;
    for (const GenTlInterfaceEntry& interface : *interfaces)
      ids += (ids.empty() ? "" : ", ") + interface.id;
    return Error{"GenTL producer " + path_.string() + ": no interface '" + interface_id +
                 "' (it has: " + (ids.empty() ? std::string("none") : ids) + ")"};
  }
  return devices;
}

Expected<GenTlListing> ListGenTlProducer(const std::filesystem::path& cti,
                                         std::chrono::milliseconds timeout) {
  auto producer = GenTlProducer::Load(cti);
  if (!producer) return producer.error();
  GenTlListing listing;
  listing.producer = (*producer)->Info();
  auto interfaces = (*producer)->Interfaces(timeout);
  if (!interfaces) return interfaces.error();
  listing.interfaces = std::move(*interfaces);
  auto devices = (*producer)->Devices("", timeout);
  if (!devices) return devices.error();
  listing.devices = std::move(*devices);
  return listing;
}

}  // namespace lifmcr
