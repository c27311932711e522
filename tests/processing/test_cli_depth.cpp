// `lifmcr grid` and `lifmcr depth` on a synthetic dataset written by
// `lifmcr synth` (small preset, one camera, one frame).

#include "replay/synth/gt_images.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

TEST(CliDepth, GridAndDepthOnASyntheticDataset) {
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + dir.path().string() + " --preset small --frames 1 --cameras 1 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path calib = dir / "Calibration";
  const fs::path seq = dir / "00_Synthetic" / "Sequence_00";
  const std::string serial = "40398678";

  const fs::path white = calib / "01_White_Images" / ("TypeE_" + serial + "_00_Raw.bmp");
  const fs::path mla = calib / "02_MLA_Calibration" / ("TypeE_" + serial + "_MLA.xml");
  const fs::path fitted = dir / "fitted_MLA.xml";
  const test::CommandResult grid = test::RunLifmcr("grid " + white.string() + " --mla " +
                                                   mla.string() + " --out " + fitted.string());
  ASSERT_EQ(grid.exit_code, 0) << grid.err;
  EXPECT_NE(grid.out.find("residual"), std::string::npos) << grid.out;
  EXPECT_NE(grid.out.find("centres differ by"), std::string::npos) << grid.out;
  EXPECT_TRUE(fs::exists(fitted));

  const fs::path out = dir / "depth";
  const test::CommandResult depth = test::RunLifmcr(
      "depth " + seq.string() + " --camera " + serial + " --frame 0 --out " + out.string() +
      " --intrinsics " + (seq / "GroundTruth" / "cameras.yaml").string() + " --uncertainty");
  ASSERT_EQ(depth.exit_code, 0) << depth.err << depth.out;
  EXPECT_NE(depth.out.find("raw MP/s"), std::string::npos) << depth.out;
  const std::string stem = serial + "_000000";
  for (const char* suffix : {"_virtual_depth.tiff", "_confidence.tiff", "_virtual_depth_tf.tiff",
                             "_depth_mm.tiff", "_tf.png", "_depth.png", "_points.ply"})
    EXPECT_TRUE(fs::exists(out / (stem + suffix))) << suffix;
  {
    // Binary PLY with the per-point uncertainty as a named property.
    std::ifstream ply(out / (stem + "_points.ply"), std::ios::binary);
    std::string header, line;
    while (std::getline(ply, line) && line != "end_header") header += line + "\n";
    EXPECT_NE(header.find("format binary_little_endian"), std::string::npos) << header;
    EXPECT_NE(header.find("property float sigma_z_mm"), std::string::npos) << header;
    EXPECT_NE(header.find("property uchar red"), std::string::npos) << header;
  }
  int w = 0, h = 0;
  Expected<std::vector<float>> v =
      synth::ReadFloatTiff(out / (stem + "_virtual_depth.tiff"), &w, &h);
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(w, 1024);
  EXPECT_EQ(h, 768);
  Expected<std::vector<float>> mm = synth::ReadFloatTiff(out / (stem + "_depth_mm.tiff"), &w, &h);
  ASSERT_TRUE(mm.ok());
  EXPECT_EQ(w, 512);
  EXPECT_EQ(h, 384);

  // A user error is a message and exit code 1.
  const test::CommandResult missing = test::RunLifmcr(
      "depth " + seq.string() + " --camera 11111111 --frame 0 --out " + out.string());
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("11111111"), std::string::npos) << missing.err;
}

}  // namespace
}  // namespace lifmcr
