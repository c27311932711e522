#pragma once
// The GenApi engine of the GenTL driver: an ArvDevice (Aravis's public,
// derivable device class) whose memory reads and writes go through a GenTL
// port (GCReadPort/GCWritePort), with Aravis's own GenICam node map (ArvGc)
// built from the XML the port describes (GCGetPortURL / GCGetPortURLInfo).
// Wrapped in an ArvCamera (arv_camera_new_with_device), it gives the GenTL
// driver the same feature code as the Aravis driver (drivers/arv_settings.h):
// trigger, exposure, gain, pixel format, region, acquisition start/stop.
//
// The XML is read from the device ("Local:name.xml;address;length", hex,
// optionally zipped) or from a file ("file:///path"); an http URL is refused.
//
// Includes <arv.h>: for drivers/*.cpp only, never a public header.

#include "config/error.h"
#include "drivers/gentl_producer.h"

#include <arv.h>

#include <memory>
#include <string>

namespace lifmcr {

// A new ArvDevice (one reference, the caller's) over `port` of `producer`,
// its node map built; an error naming the URL or the GenTL call that failed.
Expected<ArvDevice*> NewGenTlArvDevice(std::shared_ptr<GenTlProducer> producer,
                                       gentl::PORT_HANDLE port);

// The GenTL error of the last failed port access on `device` (0 when none
// failed): GC_ERR_IO / GC_ERR_INVALID_HANDLE / GC_ERR_NOT_AVAILABLE mean the
// device is gone rather than a value refused.
gentl::GC_ERROR GenTlArvDeviceLastError(ArvDevice* device);

}  // namespace lifmcr
