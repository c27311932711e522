#include "drivers/gentl_arv_device.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <fstream>
#include <sstream>
#include <vector>

namespace lifmcr {
namespace {

using namespace gentl;

// What the GObject instance points to; GObject memory is not constructed by
// C++, so the state lives on the heap and is deleted in finalize.
struct PortState {
  std::shared_ptr<GenTlProducer> producer;
  PORT_HANDLE port = nullptr;
  std::string xml;
  ArvGc* genicam = nullptr;
  std::atomic<GC_ERROR> last_error{GC_ERR_SUCCESS};
};

}  // namespace
}  // namespace lifmcr

extern "C" {

typedef struct {
  ArvDevice parent;
  lifmcr::PortState* state;
} LifmcrGenTlDevice;

typedef struct {
  ArvDeviceClass parent_class;
} LifmcrGenTlDeviceClass;

G_DEFINE_TYPE(LifmcrGenTlDevice, lifmcr_gentl_device, ARV_TYPE_DEVICE)

}  // extern "C"

namespace lifmcr {
namespace {

PortState* State(ArvDevice* device) {
  return G_TYPE_CHECK_INSTANCE_TYPE(device, lifmcr_gentl_device_get_type())
             ? reinterpret_cast<LifmcrGenTlDevice*>(device)->state
             : nullptr;
}

gboolean Fail(PortState* state, GC_ERROR code, const char* call, GError** error) {
  state->last_error.store(code);
  const int arv_code =
      code == GC_ERR_TIMEOUT ? ARV_DEVICE_ERROR_TIMEOUT
      : (code == GC_ERR_IO || code == GC_ERR_INVALID_HANDLE || code == GC_ERR_NOT_AVAILABLE)
          ? ARV_DEVICE_ERROR_NOT_CONNECTED
          : ARV_DEVICE_ERROR_TRANSFER_ERROR;
  const std::string text = state->producer->Describe(code, call);
  g_set_error(error, ARV_DEVICE_ERROR, arv_code, "%s", text.c_str());
  return FALSE;
}

gboolean ReadMemory(ArvDevice* device, guint64 address, guint32 size, void* buffer,
                    GError** error) {
  PortState* state = State(device);
  std::size_t done = size;
  const GC_ERROR code = state->producer->fn().GCReadPort(state->port, address, buffer, &done);
  if (code != GC_ERR_SUCCESS) return Fail(state, code, "GCReadPort", error);
  if (done != size) return Fail(state, GC_ERR_IO, "GCReadPort (short read)", error);
  return TRUE;
}

gboolean WriteMemory(ArvDevice* device, guint64 address, guint32 size, void* buffer,
                     GError** error) {
  PortState* state = State(device);
  std::size_t done = size;
  const GC_ERROR code = state->producer->fn().GCWritePort(state->port, address, buffer, &done);
  if (code != GC_ERR_SUCCESS) return Fail(state, code, "GCWritePort", error);
  if (done != size) return Fail(state, GC_ERR_IO, "GCWritePort (short write)", error);
  return TRUE;
}

// 32-bit registers in the port's byte order are what the node map's
// registers already describe; these two exist for Aravis's own callers.
gboolean ReadRegister(ArvDevice* device, guint64 address, guint32* value, GError** error) {
  return ReadMemory(device, address, sizeof(*value), value, error);
}
gboolean WriteRegister(ArvDevice* device, guint64 address, guint32 value, GError** error) {
  return WriteMemory(device, address, sizeof(value), &value, error);
}

const char* GenicamXml(ArvDevice* device, size_t* size) {
  PortState* state = State(device);
  *size = state->xml.size();
  return state->xml.c_str();
}

ArvGc* Genicam(ArvDevice* device) { return State(device)->genicam; }

ArvStream* CreateStream(ArvDevice*, ArvStreamCallback, void*, GDestroyNotify, GError** error) {
  g_set_error(error, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_NO_STREAM_CHANNEL,
              "a GenTL device streams through its producer's data stream, not Aravis");
  return nullptr;
}

}  // namespace
}  // namespace lifmcr

extern "C" {

static void lifmcr_gentl_device_init(LifmcrGenTlDevice* self) { self->state = nullptr; }

static void lifmcr_gentl_device_finalize(GObject* object) {
  LifmcrGenTlDevice* self = reinterpret_cast<LifmcrGenTlDevice*>(object);
  if (self->state != nullptr) {
    g_clear_object(&self->state->genicam);
    delete self->state;
    self->state = nullptr;
  }
  G_OBJECT_CLASS(lifmcr_gentl_device_parent_class)->finalize(object);
}

static void lifmcr_gentl_device_class_init(LifmcrGenTlDeviceClass* klass) {
  GObjectClass* object_class = G_OBJECT_CLASS(klass);
  ArvDeviceClass* device_class = ARV_DEVICE_CLASS(klass);
  object_class->finalize = lifmcr_gentl_device_finalize;
  device_class->create_stream = lifmcr::CreateStream;
  device_class->get_genicam_xml = lifmcr::GenicamXml;
  device_class->get_genicam = lifmcr::Genicam;
  device_class->read_memory = lifmcr::ReadMemory;
  device_class->write_memory = lifmcr::WriteMemory;
  device_class->read_register = lifmcr::ReadRegister;
  device_class->write_register = lifmcr::WriteRegister;
}

}  // extern "C"

namespace lifmcr {
namespace {

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

bool EndsWith(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         Lower(text.substr(text.size() - suffix.size())) == Lower(suffix);
}

// The first URL the port lists: GCGetPortURLInfo (GenTL >= 1.1), else the
// older GCGetPortURL.
Expected<std::string> PortUrl(GenTlProducer& producer, PORT_HANDLE port) {
  const Functions& fn = producer.fn();
  std::uint32_t count = 0;
  if (fn.GCGetNumPortURLs != nullptr && fn.GCGetPortURLInfo != nullptr &&
      fn.GCGetNumPortURLs(port, &count) == GC_ERR_SUCCESS && count > 0) {
    std::string url = GenTlInfoString([&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
      return fn.GCGetPortURLInfo(port, 0, URL_INFO_URL, type, buffer, size);
    });
    if (!url.empty()) return url;
  }
  std::size_t size = 0;
  if (GC_ERROR code = fn.GCGetPortURL(port, nullptr, &size); code != GC_ERR_SUCCESS)
    return Error{producer.Describe(code, "GCGetPortURL")};
  std::string url(size, '\0');
  if (GC_ERROR code = fn.GCGetPortURL(port, url.data(), &size); code != GC_ERR_SUCCESS)
    return Error{producer.Describe(code, "GCGetPortURL")};
  while (!url.empty() && url.back() == '\0') url.pop_back();
  return url;
}

Expected<std::string> Unzip(const std::string& data, const std::string& url) {
  ArvZip* zip = arv_zip_new(data.data(), data.size());
  if (zip == nullptr) return Error{"GenICam XML at " + url + ": not a readable zip file"};
  std::string xml;
  for (const GSList* item = arv_zip_get_file_list(zip); item != nullptr; item = item->next) {
    const char* name = arv_zip_file_get_name(static_cast<ArvZipFile*>(item->data));
    if (name == nullptr || !EndsWith(name, ".xml")) continue;
    std::size_t size = 0;
    void* bytes = arv_zip_get_file(zip, name, &size);
    if (bytes != nullptr) xml.assign(static_cast<const char*>(bytes), size);
    g_free(bytes);
    break;
  }
  arv_zip_free(zip);
  if (xml.empty()) return Error{"GenICam XML at " + url + ": the zip holds no .xml file"};
  return xml;
}

Expected<std::string> ReadXml(GenTlProducer& producer, PORT_HANDLE port) {
  auto url = PortUrl(producer, port);
  if (!url) return url.error();
  const std::string lower = Lower(*url);
  std::string name;
  std::string data;
  if (lower.rfind("local:", 0) == 0) {
    // Local:[///]name;address;length[?SchemaVersion=x.y.z], address and length in hex.
    std::string rest = url->substr(6);
    if (const std::size_t query = rest.find('?'); query != std::string::npos) rest.resize(query);
    while (!rest.empty() && rest.front() == '/') rest.erase(rest.begin());
    std::vector<std::string> fields;
    std::stringstream stream(rest);
    for (std::string field; std::getline(stream, field, ';');) fields.push_back(field);
    if (fields.size() != 3)
      return Error{"GenICam XML URL '" + *url + "': expected Local:name;address;length"};
    name = fields[0];
    std::uint64_t address = 0, length = 0;
    try {
      address = std::stoull(fields[1], nullptr, 16);
      length = std::stoull(fields[2], nullptr, 16);
    } catch (const std::exception&) {
      return Error{"GenICam XML URL '" + *url + "': address and length must be hexadecimal"};
    }
    if (length == 0 || length > (64u << 20))
      return Error{"GenICam XML URL '" + *url + "': implausible length " + fields[2]};
    data.resize(length);
    std::size_t size = length;
    if (GC_ERROR code = producer.fn().GCReadPort(port, address, data.data(), &size);
        code != GC_ERR_SUCCESS)
      return Error{"reading the GenICam XML (" + *url +
                   "): " + producer.Describe(code, "GCReadPort")};
    data.resize(size);
  } else if (lower.rfind("file:", 0) == 0) {
    std::string path = url->substr(5);
    if (const std::size_t query = path.find('?'); query != std::string::npos) path.resize(query);
    if (path.rfind("///", 0) == 0) path.erase(0, 2);  // file:///abs -> /abs
    name = path;
    std::ifstream file(path, std::ios::binary);
    if (!file) return Error{"GenICam XML URL '" + *url + "': cannot read " + path};
    data.assign(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
  } else {
    return Error{"GenICam XML URL '" + *url +
                 "': only Local: and file: URLs are supported (no downloads)"};
  }
  if (EndsWith(name, ".zip")) return Unzip(data, *url);
  while (!data.empty() && data.back() == '\0') data.pop_back();
  return data;
}

}  // namespace

Expected<ArvDevice*> NewGenTlArvDevice(std::shared_ptr<GenTlProducer> producer,
                                       gentl::PORT_HANDLE port) {
  auto xml = ReadXml(*producer, port);
  if (!xml) return xml.error();
  if (xml->find("<RegisterDescription") == std::string::npos)
    return Error{"the device's GenICam XML has no RegisterDescription element"};
  auto* device =
      static_cast<LifmcrGenTlDevice*>(g_object_new(lifmcr_gentl_device_get_type(), nullptr));
  device->state = new PortState();
  device->state->producer = std::move(producer);
  device->state->port = port;
  device->state->xml = std::move(*xml);
  ArvDevice* arv_device = ARV_DEVICE(device);
  device->state->genicam =
      arv_gc_new(arv_device, device->state->xml.data(), device->state->xml.size());
  if (device->state->genicam == nullptr) {
    g_object_unref(device);
    return Error{"the device's GenICam XML could not be parsed"};
  }
  // Every read goes to the device: the driver's probe reads a register to
  // learn whether the device still answers.
  arv_gc_set_register_cache_policy(device->state->genicam, ARV_REGISTER_CACHE_POLICY_DISABLE);
  return arv_device;
}

gentl::GC_ERROR GenTlArvDeviceLastError(ArvDevice* device) {
  PortState* state = State(device);
  return state != nullptr ? state->last_error.load() : gentl::GC_ERR_SUCCESS;
}

}  // namespace lifmcr
