// `--cameras SERIAL[,SERIAL...]` of `lifmcr replay` and `lifmcr record`: a
// serial that is not in the sequence or the rig file, an empty item and a
// serial given twice are refused with the serial and the cameras there,
// before any camera is opened; --extrinsics-csv and --rigid-mount belong to
// `lifmcr relate` when a process holds only some cameras.
#include "config/rig_config.h"
#include "replay/layout.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

TEST(CliCameras, ReplayNamesAnUnknownSerialAndTheSequencesCameras) {
  test::TempDir dir;
  const fs::path seq = dir / "00_Scene" / "seq";
  for (const char* serial : {"40398673", "40398678"})
    test::WriteFile(layout::CameraDir(seq, serial) / layout::RawFrameFileName(serial, 0), "BM");
  const test::CommandResult unknown =
      test::RunLifmcr("replay " + seq.string() + " --rate max --lcm memq:// --cameras 123");
  EXPECT_EQ(unknown.exit_code, 2);  // a usage error, as record's
  EXPECT_NE(unknown.err.find("--cameras: camera '123' is not in " + seq.string() +
                             " (its cameras: 40398673, 40398678)"),
            std::string::npos)
      << unknown.err;
  const test::CommandResult empty =
      test::RunLifmcr("replay " + seq.string() + " --lcm memq:// --cameras 40398673,");
  EXPECT_EQ(empty.exit_code, 2);
  EXPECT_NE(empty.err.find("an empty serial"), std::string::npos) << empty.err;
  const test::CommandResult twice =
      test::RunLifmcr("replay " + seq.string() + " --lcm memq:// --cameras 40398673,40398673");
  EXPECT_EQ(twice.exit_code, 2);
  EXPECT_NE(twice.err.find("camera '40398673' given twice"), std::string::npos) << twice.err;
}

TEST(CliCameras, RecordNamesAnUnknownSerialAndTheRigFilesCameras) {
  test::TempDir dir;
  const fs::path mla =
      fs::path(LIFMCR_SOURCE_DIR) / "config/examples/Calibration/02_MLA_Calibration";
  RigConfig rig;
  rig.name = "two";
  for (int i = 0; i < 2; ++i) {
    CameraConfig camera;
    camera.serial = i == 0 ? "MEMA" : "MEMB";
    camera.name = "cam" + std::to_string(i);
    camera.role = i == 0 ? CameraRole::kReference : CameraRole::kRegistered;
    camera.driver.kind = DriverKind::kReplay;
    camera.mla_file = mla / (i == 0 ? "TypeE_40398678_MLA.xml" : "TypeE_40398673_MLA.xml");
    rig.cameras.push_back(camera);
  }
  const fs::path rig_path = dir / "rig.yaml";
  test::WriteFile(rig_path, FormatRigConfig(rig));
  const test::CommandResult unknown =
      test::RunLifmcr("record --rig " + rig_path.string() + " --out " + (dir / "out").string() +
                      " --cameras MEMB,MEMC");
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.err.find("--cameras: camera 'MEMC' is not in " + rig_path.string() +
                             " (its cameras: MEMA, MEMB)"),
            std::string::npos)
      << unknown.err;
  EXPECT_FALSE(fs::exists(dir / "out")) << "nothing recorded";
}

}  // namespace
}  // namespace lifmcr
