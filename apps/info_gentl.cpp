#include "apps/info_gentl.h"

#include "drivers/gentl_producer.h"

#include <sstream>

namespace lifmcr::apps {

using nlohmann::json;

namespace {

constexpr std::chrono::milliseconds kDiscoveryTimeout{500};

}  // namespace

json DescribeGenTlProducer(const std::filesystem::path& cti) {
  json out{{"cti", cti.string()}, {"problems", json::array()}};
  auto listing = ListGenTlProducer(cti, kDiscoveryTimeout);
  if (!listing) {
    out["problems"].push_back(listing.error().message);
    return out;
  }
  const GenTlProducerInfo& p = listing->producer;
  out["producer"] = {{"vendor", p.vendor},   {"model", p.model},
                     {"version", p.version}, {"tl_type", p.tl_type},
                     {"gentl_version", p.gentl_version}};
  out["interfaces"] = json::array();
  for (const GenTlInterfaceEntry& interface : listing->interfaces)
    out["interfaces"].push_back({{"id", interface.id},
                                 {"display_name", interface.display_name},
                                 {"tl_type", interface.tl_type}});
  out["devices"] = json::array();
  for (const GenTlDeviceEntry& device : listing->devices)
    out["devices"].push_back({{"interface", device.interface_id},
                              {"id", device.id},
                              {"serial", device.serial},
                              {"vendor", device.vendor},
                              {"model", device.model},
                              {"tl_type", device.tl_type},
                              {"access", std::string(gentl::AccessStatusName(device.access))}});
  return out;
}

json DescribeGenTlCamera(const CameraConfig& camera) {
  const std::string wanted = camera.driver.device.empty() ? camera.serial : camera.driver.device;
  std::vector<std::filesystem::path> candidates;
  if (!camera.driver.cti.empty())
    candidates.push_back(camera.driver.cti);
  else
    candidates = GenTlProducer::SearchPath();
  if (candidates.empty())
    return json{{"device", wanted},
                {"device_found", false},
                {"problems",
                 {"camera " + camera.name +
                  ": no cti and no .cti in the directories of GENICAM_GENTL64_PATH"}}};
  json out;
  for (const std::filesystem::path& cti : candidates) {
    out = DescribeGenTlProducer(cti);
    bool found = false;
    for (const json& device : out.value("devices", json::array()))
      if ((device["id"] == wanted || device["serial"] == wanted) &&
          (camera.driver.interface_id.empty() || device["interface"] == camera.driver.interface_id))
        found = true;
    out["device"] = wanted;
    out["device_found"] = found;
    if (found) return out;
  }
  if (out.contains("producer"))
    out["problems"].push_back("camera " + camera.name + ": device '" + wanted + "'" +
                              (camera.driver.interface_id.empty()
                                   ? std::string()
                                   : " on interface " + camera.driver.interface_id) +
                              " not listed by " + out["cti"].get<std::string>());
  else
    out.erase("device_found");  // the producer could not be asked
  return out;
}

std::string FormatGenTlText(const json& gentl, const std::string& indent) {
  std::ostringstream out;
  if (gentl.contains("cti")) out << indent << "GenTL producer " << gentl["cti"].get<std::string>();
  if (gentl.contains("producer")) {
    const json& p = gentl["producer"];
    out << ": " << p.value("vendor", "") << " " << p.value("model", "") << " "
        << p.value("version", "") << ", " << p.value("tl_type", "") << ", GenTL "
        << p.value("gentl_version", "?");
  }
  out << "\n";
  for (const json& interface : gentl.value("interfaces", json::array()))
    out << indent << "  interface " << interface["id"].get<std::string>() << " ("
        << interface["display_name"].get<std::string>() << ", "
        << interface["tl_type"].get<std::string>() << ")\n";
  for (const json& device : gentl.value("devices", json::array()))
    out << indent << "  device " << device["id"].get<std::string>() << " on "
        << device["interface"].get<std::string>() << ": serial "
        << device["serial"].get<std::string>() << ", " << device["vendor"].get<std::string>()
        << " " << device["model"].get<std::string>() << ", "
        << device["access"].get<std::string>() << "\n";
  if (gentl.contains("device_found"))
    out << indent << "  this camera's device " << gentl["device"].get<std::string>() << ": "
        << (gentl["device_found"].get<bool>() ? "listed" : "NOT listed") << "\n";
  // In a rig file's report these do not make the rig file wrong (the
  // producer belongs to the recording machine): "cannot check".
  const bool in_rig = gentl.contains("device");
  for (const json& problem : gentl.value("problems", json::array()))
    out << indent << (in_rig ? "  cannot check: " : "  problem: ") << problem.get<std::string>()
        << "\n";
  return out.str();
}

}  // namespace lifmcr::apps
