#pragma once
// The parts of the EMVA GenICam GenTL C interface (standard version 1.5)
// that lifmcr uses, declared by the project from the published standard:
// handle and value types, error codes, the info/command enumerations and one
// function-pointer type per entry point. A producer (.cti) is a shared
// library exporting these functions under their plain C names; the driver
// loads it with dlopen (drivers/gentl_producer.h) and the test producer
// (tests/drivers/gentl_sim/) implements them.
//
// Values are fixed by the standard, so a producer built against the EMVA
// header and this file agree on every number below. On Linux the calling
// convention is the platform's default one; structures passed through the
// interface are packed to 1 byte, as the standard specifies.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace lifmcr::gentl {

using GC_ERROR = std::int32_t;
using INFO_DATATYPE = std::int32_t;
using bool8_t = std::uint8_t;

using TL_HANDLE = void*;
using IF_HANDLE = void*;
using DEV_HANDLE = void*;
using DS_HANDLE = void*;
using PORT_HANDLE = void*;  // a TL, IF, DEV, DS or BUFFER handle, or the remote device's port
using BUFFER_HANDLE = void*;
using EVENTSRC_HANDLE = void*;
using EVENT_HANDLE = void*;

inline constexpr std::uint64_t kInfinite = 0xFFFFFFFFFFFFFFFFULL;  // GENTL_INFINITE

enum : GC_ERROR {
  GC_ERR_SUCCESS = 0,
  GC_ERR_ERROR = -1001,
  GC_ERR_NOT_INITIALIZED = -1002,
  GC_ERR_NOT_IMPLEMENTED = -1003,
  GC_ERR_RESOURCE_IN_USE = -1004,
  GC_ERR_ACCESS_DENIED = -1005,
  GC_ERR_INVALID_HANDLE = -1006,
  GC_ERR_INVALID_ID = -1007,
  GC_ERR_NO_DATA = -1008,
  GC_ERR_INVALID_PARAMETER = -1009,
  GC_ERR_IO = -1010,
  GC_ERR_TIMEOUT = -1011,
  GC_ERR_ABORT = -1012,
  GC_ERR_INVALID_BUFFER = -1013,
  GC_ERR_NOT_AVAILABLE = -1014,
  GC_ERR_INVALID_ADDRESS = -1015,
  GC_ERR_BUFFER_TOO_SMALL = -1016,
  GC_ERR_INVALID_INDEX = -1017,
  GC_ERR_PARSING_CHUNK_DATA = -1018,
  GC_ERR_INVALID_VALUE = -1019,
  GC_ERR_RESOURCE_EXHAUSTED = -1020,
  GC_ERR_OUT_OF_MEMORY = -1021,
  GC_ERR_BUSY = -1022,
  GC_ERR_CUSTOM_ID = -10000,
};

// "GC_ERR_TIMEOUT"; "GC_ERR_CUSTOM_ID-7" for producer-specific codes below
// GC_ERR_CUSTOM_ID; "GC_ERROR(n)" for anything else.
std::string ErrorName(GC_ERROR code);

enum : INFO_DATATYPE {
  INFO_DATATYPE_UNKNOWN = 0,
  INFO_DATATYPE_STRING = 1,
  INFO_DATATYPE_STRINGLIST = 2,
  INFO_DATATYPE_INT16 = 3,
  INFO_DATATYPE_UINT16 = 4,
  INFO_DATATYPE_INT32 = 5,
  INFO_DATATYPE_UINT32 = 6,
  INFO_DATATYPE_INT64 = 7,
  INFO_DATATYPE_UINT64 = 8,
  INFO_DATATYPE_FLOAT64 = 9,
  INFO_DATATYPE_PTR = 10,
  INFO_DATATYPE_BOOL8 = 11,
  INFO_DATATYPE_SIZET = 12,
  INFO_DATATYPE_BUFFER = 13,
  INFO_DATATYPE_PTRDIFF = 14,
};

using TL_INFO_CMD = std::int32_t;
enum : TL_INFO_CMD {
  TL_INFO_ID = 0,
  TL_INFO_VENDOR = 1,
  TL_INFO_MODEL = 2,
  TL_INFO_VERSION = 3,
  TL_INFO_TLTYPE = 4,
  TL_INFO_NAME = 5,
  TL_INFO_PATHNAME = 6,
  TL_INFO_DISPLAYNAME = 7,
  TL_INFO_CHAR_ENCODING = 8,
  TL_INFO_GENTL_VER_MAJOR = 9,
  TL_INFO_GENTL_VER_MINOR = 10,
};

using INTERFACE_INFO_CMD = std::int32_t;
enum : INTERFACE_INFO_CMD {
  INTERFACE_INFO_ID = 0,
  INTERFACE_INFO_DISPLAYNAME = 1,
  INTERFACE_INFO_TLTYPE = 2,
};

using DEVICE_ACCESS_FLAGS = std::int32_t;
enum : DEVICE_ACCESS_FLAGS {
  DEVICE_ACCESS_UNKNOWN = 0,
  DEVICE_ACCESS_NONE = 1,
  DEVICE_ACCESS_READONLY = 2,
  DEVICE_ACCESS_CONTROL = 3,
  DEVICE_ACCESS_EXCLUSIVE = 4,
};

using DEVICE_ACCESS_STATUS = std::int32_t;
enum : DEVICE_ACCESS_STATUS {
  DEVICE_ACCESS_STATUS_UNKNOWN = 0,
  DEVICE_ACCESS_STATUS_READWRITE = 1,
  DEVICE_ACCESS_STATUS_READONLY = 2,
  DEVICE_ACCESS_STATUS_NOACCESS = 3,
  DEVICE_ACCESS_STATUS_BUSY = 4,
  DEVICE_ACCESS_STATUS_OPEN_READWRITE = 5,
  DEVICE_ACCESS_STATUS_OPEN_READONLY = 6,
};
// "busy (opened by another process or host)", "readwrite", ...
std::string_view AccessStatusName(DEVICE_ACCESS_STATUS status);

using DEVICE_INFO_CMD = std::int32_t;
enum : DEVICE_INFO_CMD {
  DEVICE_INFO_ID = 0,
  DEVICE_INFO_VENDOR = 1,
  DEVICE_INFO_MODEL = 2,
  DEVICE_INFO_TLTYPE = 3,
  DEVICE_INFO_DISPLAYNAME = 4,
  DEVICE_INFO_ACCESS_STATUS = 5,
  DEVICE_INFO_USER_DEFINED_NAME = 6,
  DEVICE_INFO_SERIAL_NUMBER = 7,
  DEVICE_INFO_VERSION = 8,
  DEVICE_INFO_TIMESTAMP_FREQUENCY = 9,
};

using ACQ_STOP_FLAGS = std::int32_t;
enum : ACQ_STOP_FLAGS { ACQ_STOP_FLAGS_DEFAULT = 0, ACQ_STOP_FLAGS_KILL = 1 };
using ACQ_START_FLAGS = std::int32_t;
enum : ACQ_START_FLAGS { ACQ_START_FLAGS_DEFAULT = 0 };

using ACQ_QUEUE_TYPE = std::int32_t;
enum : ACQ_QUEUE_TYPE {
  ACQ_QUEUE_INPUT_TO_OUTPUT = 0,
  ACQ_QUEUE_OUTPUT_DISCARD = 1,
  ACQ_QUEUE_ALL_TO_INPUT = 2,
  ACQ_QUEUE_UNQUEUED_TO_INPUT = 3,
  ACQ_QUEUE_ALL_DISCARD = 4,
};

using STREAM_INFO_CMD = std::int32_t;
enum : STREAM_INFO_CMD {
  STREAM_INFO_ID = 0,
  STREAM_INFO_NUM_DELIVERED = 1,
  STREAM_INFO_NUM_UNDERRUN = 2,
  STREAM_INFO_NUM_ANNOUNCED = 3,
  STREAM_INFO_NUM_QUEUED = 4,
  STREAM_INFO_NUM_AWAIT_DELIVERY = 5,
  STREAM_INFO_NUM_STARTED = 6,
  STREAM_INFO_PAYLOAD_SIZE = 7,
  STREAM_INFO_IS_GRABBING = 8,
  STREAM_INFO_DEFINES_PAYLOADSIZE = 9,
  STREAM_INFO_TLTYPE = 10,
  STREAM_INFO_NUM_CHUNKS_MAX = 11,
  STREAM_INFO_BUF_ANNOUNCE_MIN = 12,
  STREAM_INFO_BUF_ALIGNMENT = 13,
};

using BUFFER_INFO_CMD = std::int32_t;
enum : BUFFER_INFO_CMD {
  BUFFER_INFO_BASE = 0,
  BUFFER_INFO_SIZE = 1,
  BUFFER_INFO_USER_PTR = 2,
  BUFFER_INFO_TIMESTAMP = 3,
  BUFFER_INFO_NEW_DATA = 4,
  BUFFER_INFO_IS_QUEUED = 5,
  BUFFER_INFO_IS_ACQUIRING = 6,
  BUFFER_INFO_IS_INCOMPLETE = 7,
  BUFFER_INFO_TLTYPE = 8,
  BUFFER_INFO_SIZE_FILLED = 9,
  BUFFER_INFO_WIDTH = 10,
  BUFFER_INFO_HEIGHT = 11,
  BUFFER_INFO_XOFFSET = 12,
  BUFFER_INFO_YOFFSET = 13,
  BUFFER_INFO_XPADDING = 14,
  BUFFER_INFO_YPADDING = 15,
  BUFFER_INFO_FRAMEID = 16,
  BUFFER_INFO_IMAGEPRESENT = 17,
  BUFFER_INFO_IMAGEOFFSET = 18,
  BUFFER_INFO_PAYLOADTYPE = 19,
  BUFFER_INFO_PIXELFORMAT = 20,
  BUFFER_INFO_PIXELFORMAT_NAMESPACE = 21,
  BUFFER_INFO_DELIVERED_IMAGEHEIGHT = 22,
  BUFFER_INFO_DELIVERED_CHUNKPAYLOADSIZE = 23,
  BUFFER_INFO_CHUNKLAYOUTID = 24,
  BUFFER_INFO_FILENAME = 25,
  BUFFER_INFO_PIXEL_ENDIANNESS = 26,
  BUFFER_INFO_DATA_SIZE = 27,
  BUFFER_INFO_TIMESTAMP_NS = 28,
  BUFFER_INFO_DATA_LARGER_THAN_BUFFER = 29,
  BUFFER_INFO_CONTAINS_CHUNKDATA = 30,
};

enum : std::int32_t {
  PAYLOAD_TYPE_UNKNOWN = 0,
  PAYLOAD_TYPE_IMAGE = 1,
  PAYLOAD_TYPE_RAW_DATA = 2,
  PAYLOAD_TYPE_CHUNK_DATA = 4,
};

enum : std::int32_t {
  PIXELFORMAT_NAMESPACE_UNKNOWN = 0,
  PIXELFORMAT_NAMESPACE_GEV = 1,
  PIXELFORMAT_NAMESPACE_IIDC = 2,
  PIXELFORMAT_NAMESPACE_PFNC_16BIT = 3,
  PIXELFORMAT_NAMESPACE_PFNC_32BIT = 4,
};

using PORT_INFO_CMD = std::int32_t;
enum : PORT_INFO_CMD {
  PORT_INFO_ID = 0,
  PORT_INFO_VENDOR = 1,
  PORT_INFO_MODEL = 2,
  PORT_INFO_TLTYPE = 3,
  PORT_INFO_MODULE = 4,
  PORT_INFO_LITTLE_ENDIAN = 5,
  PORT_INFO_BIG_ENDIAN = 6,
  PORT_INFO_ACCESS_READ = 7,
  PORT_INFO_ACCESS_WRITE = 8,
  PORT_INFO_ACCESS_NA = 9,
  PORT_INFO_ACCESS_NI = 10,
  PORT_INFO_VERSION = 11,
  PORT_INFO_PORTNAME = 12,
};

using URL_INFO_CMD = std::int32_t;
enum : URL_INFO_CMD {
  URL_INFO_URL = 0,
  URL_INFO_SCHEMA_VER_MAJOR = 1,
  URL_INFO_SCHEMA_VER_MINOR = 2,
  URL_INFO_FILE_VER_MAJOR = 3,
  URL_INFO_FILE_VER_MINOR = 4,
  URL_INFO_FILE_VER_SUBMINOR = 5,
  URL_INFO_FILE_SHA1_HASH = 6,
  URL_INFO_FILE_REGISTER_ADDRESS = 7,
  URL_INFO_FILE_SIZE = 8,
  URL_INFO_SCHEME = 9,
  URL_INFO_FILENAME = 10,
};

using EVENT_TYPE = std::int32_t;
enum : EVENT_TYPE {
  EVENT_ERROR = 0,
  EVENT_NEW_BUFFER = 1,
  EVENT_FEATURE_INVALIDATE = 2,
  EVENT_FEATURE_CHANGE = 3,
  EVENT_REMOTE_DEVICE = 4,
  EVENT_MODULE = 5,
};

using EVENT_INFO_CMD = std::int32_t;
enum : EVENT_INFO_CMD {
  EVENT_EVENT_TYPE = 0,
  EVENT_NUM_IN_QUEUE = 1,
  EVENT_NUM_FIRED = 2,
  EVENT_SIZE_MAX = 3,
  EVENT_INFO_DATA_SIZE_MAX = 4,
};
using EVENT_DATA_INFO_CMD = std::int32_t;

#pragma pack(push, 1)
// What EventGetData returns for EVENT_NEW_BUFFER.
struct EVENT_NEW_BUFFER_DATA {
  BUFFER_HANDLE BufferHandle;
  void* pUserPointer;  // the pPrivate given to DSAnnounceBuffer
};
// One chunk in a buffer (DSGetBufferChunkData).
struct SINGLE_CHUNK_DATA {
  std::uint64_t ChunkID;
  std::ptrdiff_t ChunkOffset;
  std::size_t ChunkLength;
};
#pragma pack(pop)

extern "C" {
using PGCGetInfo = GC_ERROR (*)(TL_INFO_CMD, INFO_DATATYPE*, void*, std::size_t*);
using PGCGetLastError = GC_ERROR (*)(GC_ERROR*, char*, std::size_t*);
using PGCInitLib = GC_ERROR (*)();
using PGCCloseLib = GC_ERROR (*)();
using PGCReadPort = GC_ERROR (*)(PORT_HANDLE, std::uint64_t, void*, std::size_t*);
using PGCWritePort = GC_ERROR (*)(PORT_HANDLE, std::uint64_t, const void*, std::size_t*);
using PGCGetPortURL = GC_ERROR (*)(PORT_HANDLE, char*, std::size_t*);
using PGCGetPortInfo = GC_ERROR (*)(PORT_HANDLE, PORT_INFO_CMD, INFO_DATATYPE*, void*,
                                    std::size_t*);
using PGCGetNumPortURLs = GC_ERROR (*)(PORT_HANDLE, std::uint32_t*);
using PGCGetPortURLInfo = GC_ERROR (*)(PORT_HANDLE, std::uint32_t, URL_INFO_CMD, INFO_DATATYPE*,
                                       void*, std::size_t*);
using PGCRegisterEvent = GC_ERROR (*)(EVENTSRC_HANDLE, EVENT_TYPE, EVENT_HANDLE*);
using PGCUnregisterEvent = GC_ERROR (*)(EVENTSRC_HANDLE, EVENT_TYPE);
using PEventGetData = GC_ERROR (*)(EVENT_HANDLE, void*, std::size_t*, std::uint64_t);
using PEventGetDataInfo = GC_ERROR (*)(EVENT_HANDLE, const void*, std::size_t, EVENT_DATA_INFO_CMD,
                                       INFO_DATATYPE*, void*, std::size_t*);
using PEventGetInfo = GC_ERROR (*)(EVENT_HANDLE, EVENT_INFO_CMD, INFO_DATATYPE*, void*,
                                   std::size_t*);
using PEventFlush = GC_ERROR (*)(EVENT_HANDLE);
using PEventKill = GC_ERROR (*)(EVENT_HANDLE);
using PTLOpen = GC_ERROR (*)(TL_HANDLE*);
using PTLClose = GC_ERROR (*)(TL_HANDLE);
using PTLGetInfo = GC_ERROR (*)(TL_HANDLE, TL_INFO_CMD, INFO_DATATYPE*, void*, std::size_t*);
using PTLGetNumInterfaces = GC_ERROR (*)(TL_HANDLE, std::uint32_t*);
using PTLGetInterfaceID = GC_ERROR (*)(TL_HANDLE, std::uint32_t, char*, std::size_t*);
using PTLGetInterfaceInfo = GC_ERROR (*)(TL_HANDLE, const char*, INTERFACE_INFO_CMD, INFO_DATATYPE*,
                                         void*, std::size_t*);
using PTLOpenInterface = GC_ERROR (*)(TL_HANDLE, const char*, IF_HANDLE*);
using PTLUpdateInterfaceList = GC_ERROR (*)(TL_HANDLE, bool8_t*, std::uint64_t);
using PIFClose = GC_ERROR (*)(IF_HANDLE);
using PIFGetInfo = GC_ERROR (*)(IF_HANDLE, INTERFACE_INFO_CMD, INFO_DATATYPE*, void*, std::size_t*);
using PIFGetNumDevices = GC_ERROR (*)(IF_HANDLE, std::uint32_t*);
using PIFGetDeviceID = GC_ERROR (*)(IF_HANDLE, std::uint32_t, char*, std::size_t*);
using PIFUpdateDeviceList = GC_ERROR (*)(IF_HANDLE, bool8_t*, std::uint64_t);
using PIFGetDeviceInfo = GC_ERROR (*)(IF_HANDLE, const char*, DEVICE_INFO_CMD, INFO_DATATYPE*,
                                      void*, std::size_t*);
using PIFOpenDevice = GC_ERROR (*)(IF_HANDLE, const char*, DEVICE_ACCESS_FLAGS, DEV_HANDLE*);
using PDevGetPort = GC_ERROR (*)(DEV_HANDLE, PORT_HANDLE*);
using PDevGetNumDataStreams = GC_ERROR (*)(DEV_HANDLE, std::uint32_t*);
using PDevGetDataStreamID = GC_ERROR (*)(DEV_HANDLE, std::uint32_t, char*, std::size_t*);
using PDevOpenDataStream = GC_ERROR (*)(DEV_HANDLE, const char*, DS_HANDLE*);
using PDevGetInfo = GC_ERROR (*)(DEV_HANDLE, DEVICE_INFO_CMD, INFO_DATATYPE*, void*, std::size_t*);
using PDevClose = GC_ERROR (*)(DEV_HANDLE);
using PDSAnnounceBuffer = GC_ERROR (*)(DS_HANDLE, void*, std::size_t, void*, BUFFER_HANDLE*);
using PDSFlushQueue = GC_ERROR (*)(DS_HANDLE, ACQ_QUEUE_TYPE);
using PDSStartAcquisition = GC_ERROR (*)(DS_HANDLE, ACQ_START_FLAGS, std::uint64_t);
using PDSStopAcquisition = GC_ERROR (*)(DS_HANDLE, ACQ_STOP_FLAGS);
using PDSGetInfo = GC_ERROR (*)(DS_HANDLE, STREAM_INFO_CMD, INFO_DATATYPE*, void*, std::size_t*);
using PDSClose = GC_ERROR (*)(DS_HANDLE);
using PDSRevokeBuffer = GC_ERROR (*)(DS_HANDLE, BUFFER_HANDLE, void**, void**);
using PDSQueueBuffer = GC_ERROR (*)(DS_HANDLE, BUFFER_HANDLE);
using PDSGetBufferInfo = GC_ERROR (*)(DS_HANDLE, BUFFER_HANDLE, BUFFER_INFO_CMD, INFO_DATATYPE*,
                                      void*, std::size_t*);
using PDSGetBufferChunkData = GC_ERROR (*)(DS_HANDLE, BUFFER_HANDLE, SINGLE_CHUNK_DATA*,
                                           std::size_t*);
}

// The entry points the driver resolves. The first group is required (a
// producer lacking one is refused, naming it); the optional ones (GenTL 1.1
// and later) are nullptr when the producer does not export them.
struct Functions {
  PGCGetInfo GCGetInfo = nullptr;
  PGCGetLastError GCGetLastError = nullptr;
  PGCInitLib GCInitLib = nullptr;
  PGCCloseLib GCCloseLib = nullptr;
  PGCReadPort GCReadPort = nullptr;
  PGCWritePort GCWritePort = nullptr;
  PGCGetPortURL GCGetPortURL = nullptr;
  PGCGetPortInfo GCGetPortInfo = nullptr;
  PGCRegisterEvent GCRegisterEvent = nullptr;
  PGCUnregisterEvent GCUnregisterEvent = nullptr;
  PEventGetData EventGetData = nullptr;
  PEventFlush EventFlush = nullptr;
  PEventKill EventKill = nullptr;
  PTLOpen TLOpen = nullptr;
  PTLClose TLClose = nullptr;
  PTLGetInfo TLGetInfo = nullptr;
  PTLGetNumInterfaces TLGetNumInterfaces = nullptr;
  PTLGetInterfaceID TLGetInterfaceID = nullptr;
  PTLGetInterfaceInfo TLGetInterfaceInfo = nullptr;
  PTLOpenInterface TLOpenInterface = nullptr;
  PTLUpdateInterfaceList TLUpdateInterfaceList = nullptr;
  PIFClose IFClose = nullptr;
  PIFGetInfo IFGetInfo = nullptr;
  PIFGetNumDevices IFGetNumDevices = nullptr;
  PIFGetDeviceID IFGetDeviceID = nullptr;
  PIFUpdateDeviceList IFUpdateDeviceList = nullptr;
  PIFGetDeviceInfo IFGetDeviceInfo = nullptr;
  PIFOpenDevice IFOpenDevice = nullptr;
  PDevGetPort DevGetPort = nullptr;
  PDevGetNumDataStreams DevGetNumDataStreams = nullptr;
  PDevGetDataStreamID DevGetDataStreamID = nullptr;
  PDevOpenDataStream DevOpenDataStream = nullptr;
  PDevGetInfo DevGetInfo = nullptr;
  PDevClose DevClose = nullptr;
  PDSAnnounceBuffer DSAnnounceBuffer = nullptr;
  PDSFlushQueue DSFlushQueue = nullptr;
  PDSStartAcquisition DSStartAcquisition = nullptr;
  PDSStopAcquisition DSStopAcquisition = nullptr;
  PDSGetInfo DSGetInfo = nullptr;
  PDSClose DSClose = nullptr;
  PDSRevokeBuffer DSRevokeBuffer = nullptr;
  PDSQueueBuffer DSQueueBuffer = nullptr;
  PDSGetBufferInfo DSGetBufferInfo = nullptr;
  // Optional (GenTL >= 1.1 / 1.3).
  PGCGetNumPortURLs GCGetNumPortURLs = nullptr;
  PGCGetPortURLInfo GCGetPortURLInfo = nullptr;
  PDSGetBufferChunkData DSGetBufferChunkData = nullptr;
};

}  // namespace lifmcr::gentl
