#pragma once
// `lifmcr info --gentl PRODUCER.cti`, and the GenTL part of `lifmcr info
// rig.yaml`: what a GenTL producer exposes (its identity, interfaces,
// devices with serial and access status), so a user finds the ids to put in
// a rig file's `driver: {kind: gentl, interface: ..., device: ...}`.

#include "config/rig_config.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace lifmcr::apps {

// {"producer": {...}, "interfaces": [...], "devices": [...]}, or
// {"problems": [message]} when the producer cannot be loaded or listed.
nlohmann::json DescribeGenTlProducer(const std::filesystem::path& cti);

// For a gentl camera of a rig file: its producer (`cti`, or the first in
// GENICAM_GENTL64_PATH) described as above, plus "device_found" (whether the
// camera's device or serial is listed) and a problem when it is not. These
// problems stay in this section: the rig file itself is not wrong when the
// producer belongs to another machine.
nlohmann::json DescribeGenTlCamera(const CameraConfig& camera);

// The text lines of either document, each indented by `indent`.
std::string FormatGenTlText(const nlohmann::json& gentl, const std::string& indent);

}  // namespace lifmcr::apps
