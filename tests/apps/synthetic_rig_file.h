#pragma once
// A rig file that serves a `lifmcr synth` dataset as hardware: every camera
// on the replay driver with a hardware trigger (`record --rig RIG --replay
// SEQ`), camera `zero` the reference, the sequence's Vicon CSV as the Vicon
// source. For the end-to-end tests of `lifmcr record`.

#include "config/rig_config.h"
#include "replay/layout.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::test {

// `data`: the dataset root synth wrote; `seq`: its sequence folder.
inline RigConfig SyntheticReplayRig(const std::string& name, const std::filesystem::path& data,
                                    const std::filesystem::path& seq,
                                    const std::vector<std::string>& serials,
                                    const std::string& zero) {
  RigConfig rig;
  rig.name = name;
  for (const std::string& serial : serials) {
    CameraConfig camera;
    camera.serial = serial;
    camera.name = "cam_" + serial;
    camera.role = serial == zero ? CameraRole::kReference : CameraRole::kRegistered;
    camera.driver.kind = DriverKind::kReplay;
    camera.trigger.mode = TriggerMode::kHardware;
    camera.mla_file =
        data / "Calibration" / "02_MLA_Calibration" / ("TypeE_" + serial + "_MLA.xml");
    rig.cameras.push_back(camera);
  }
  rig.vicon.source = ViconSourceKind::kCsv;
  rig.vicon.csv = layout::ViconCsvPath(seq, 1);
  rig.vicon.vsk = data / "Calibration" / "03_Vicon" / "Object.vsk";
  return rig;
}

}  // namespace lifmcr::test
