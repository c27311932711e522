// `lifmcr grid` and `lifmcr depth` on a synthetic dataset written by
// `lifmcr synth` (small preset, one camera, one frame).

#include "replay/bmp.h"
#include "replay/synth/gt_images.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
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
  // No white image: the lattice from the raw frame of the textured scene.
  const fs::path raw_frame = seq / ("TypeE_" + serial) / ("TypeE_" + serial + "_000000_Raw.bmp");
  const test::CommandResult textured =
      test::RunLifmcr("grid " + raw_frame.string() + " --textured --mla " + mla.string() +
                      " --out " + (dir / "textured_MLA.xml").string());
  ASSERT_EQ(textured.exit_code, 0) << textured.err;
  EXPECT_NE(textured.out.find("raw image (textured scene)"), std::string::npos) << textured.out;
  EXPECT_NE(textured.out.find("centres differ by"), std::string::npos) << textured.out;

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
  // The per-lens product: the CSV's rows are the micro images, each at its
  // cell of the lens grid TIFF with the same virtual depth.
  EXPECT_NE(depth.out.find("lens depth:"), std::string::npos) << depth.out;
  EXPECT_TRUE(fs::exists(out / (stem + "_lens_tf.png")));
  Expected<std::vector<float>> lens =
      synth::ReadFloatTiff(out / (stem + "_lens_depth.tiff"), &w, &h);
  ASSERT_TRUE(lens.ok());
  {
    std::ifstream csv(out / (stem + "_lens_depth.csv"));
    std::string line;
    ASSERT_TRUE(std::getline(csv, line));
    EXPECT_EQ(line, "col,row,i,j,type,x_px,y_px,virtual_depth,sigma_z,confidence,textured");
    int rows = 0, with_depth = 0;
    while (std::getline(csv, line)) {
      ++rows;
      int col = 0, row = 0, i = 0, j = 0, type = 0;
      double x = 0, y = 0;
      char rest[128] = {0};
      ASSERT_EQ(std::sscanf(line.c_str(), "%d,%d,%d,%d,%d,%lf,%lf,%127s", &col, &row, &i, &j, &type,
                            &x, &y, rest),
                8)
          << line;
      ASSERT_GE(col, 0);
      ASSERT_LT(col, w);
      ASSERT_GE(row, 0);
      ASSERT_LT(row, h);
      EXPECT_GE(x, -20.0);
      EXPECT_LE(x, 1024.0 + 20);
      const float in_tiff = (*lens)[static_cast<std::size_t>(row) * w + col];
      if (rest[0] != ',') {
        ++with_depth;
        EXPECT_NEAR(std::atof(rest), in_tiff, 1e-4 * in_tiff) << line;
      } else {
        EXPECT_TRUE(std::isnan(in_tiff)) << line;
      }
    }
    EXPECT_GT(rows, 1000);  // ~3700 micro images on `small`
    EXPECT_GT(with_depth, rows / 4);
  }

  // A user error is a message and exit code 1.
  const test::CommandResult missing = test::RunLifmcr(
      "depth " + seq.string() + " --camera 11111111 --frame 0 --out " + out.string());
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("11111111"), std::string::npos) << missing.err;
}

// A raw frame as a public dataset ships it: a 16-bit PNG (12 significant
// bits), no white image, the MLA file named by --mla. Same output files.
TEST(CliDepth, SixteenBitPngWithoutWhiteImage) {
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + dir.path().string() + " --preset small --frames 1 --cameras 1 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const std::string serial = "40398678";
  const fs::path seq = dir / "00_Synthetic" / "Sequence_00";
  const fs::path mla =
      dir / "Calibration" / "02_MLA_Calibration" / ("TypeE_" + serial + "_MLA.xml");
  Expected<OwnedImage> raw =
      ReadBmp(seq / ("TypeE_" + serial) / ("TypeE_" + serial + "_000000_Raw.bmp"));
  ASSERT_TRUE(raw.ok()) << raw.error().message;
  cv::Mat eight(raw->height, raw->width, raw->format == PixelFormat::kMono8 ? CV_8UC1 : CV_8UC3,
                raw->pixels.data());
  cv::Mat sixteen;
  eight.convertTo(sixteen, CV_16U, 16.0);
  const fs::path png = dir / "scene_42.png";
  ASSERT_TRUE(cv::imwrite(png.string(), sixteen));

  const fs::path out = dir / "depth";
  const test::CommandResult depth =
      test::RunLifmcr("depth --raw " + png.string() + " --mla " + mla.string() + " --camera " +
                      serial + " --intrinsics " + (seq / "GroundTruth" / "cameras.yaml").string() +
                      " --out " + out.string());
  ASSERT_EQ(depth.exit_code, 0) << depth.err << depth.out;
  EXPECT_NE(depth.out.find("PNG 16-bit colour, 12 significant bits"), std::string::npos)
      << depth.out;
  EXPECT_NE(depth.out.find("no white image: "), std::string::npos) << depth.out;
  for (const char* suffix : {"_virtual_depth.tiff", "_confidence.tiff", "_virtual_depth_tf.tiff",
                             "_depth_mm.tiff", "_tf.png", "_depth.png", "_points.ply"})
    EXPECT_TRUE(fs::exists(out / (std::string("scene_42") + suffix))) << suffix;

  // Usage errors exit 2 and say what is missing.
  const test::CommandResult no_mla =
      test::RunLifmcr("depth --raw " + png.string() + " --out " + out.string());
  EXPECT_EQ(no_mla.exit_code, 2);
  EXPECT_NE(no_mla.err.find("--mla"), std::string::npos) << no_mla.err;
  const test::CommandResult both = test::RunLifmcr("depth " + seq.string() + " --raw " +
                                                   png.string() + " --out " + out.string());
  EXPECT_EQ(both.exit_code, 2);
}

// The dense search seeded by the per-lens depth (the default) on the SIMD
// kernels and on the scalar reference (--scalar): the same maps, float for
// float (the kernels evaluate the same expressions in the same order:
// processing/lens_search_simd.h), and the same TF image byte for byte;
// --full-search runs the unseeded reference.
TEST(CliDepth, SimdAndScalarPathsWriteTheSameMaps) {
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + dir.path().string() + " --preset small --frames 1 --cameras 1 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "00_Synthetic" / "Sequence_00";
  const std::string serial = "40398678", stem = serial + "_000000";
  auto run = [&](const std::string& name, const std::string& flags) {
    const test::CommandResult r = test::RunLifmcr("depth " + seq.string() + " --camera " + serial +
                                                  " --frame 0 --out " + (dir / name).string() +
                                                  flags);
    EXPECT_EQ(r.exit_code, 0) << r.err << r.out;
    return r.out;
  };
  const std::string simd = run("simd", "");
  const std::string scalar = run("scalar", " --scalar");
  const std::string full = run("full", " --full-search");
  EXPECT_NE(simd.find("seeded by the per-lens depth"), std::string::npos) << simd;
  EXPECT_NE(scalar.find("kernels scalar"), std::string::npos) << scalar;
  EXPECT_NE(full.find("full search"), std::string::npos) << full;
  for (const char* suffix : {"_virtual_depth.tiff", "_virtual_depth_tf.tiff", "_lens_depth.tiff"}) {
    int w = 0, h = 0, w2 = 0, h2 = 0;
    Expected<std::vector<float>> a = synth::ReadFloatTiff(dir / "simd" / (stem + suffix), &w, &h);
    Expected<std::vector<float>> b =
        synth::ReadFloatTiff(dir / "scalar" / (stem + suffix), &w2, &h2);
    ASSERT_TRUE(a.ok() && b.ok()) << suffix;
    ASSERT_EQ(a->size(), b->size()) << suffix;
    long long finite = 0;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const float x = (*a)[i], y = (*b)[i];
      ASSERT_TRUE((std::isnan(x) && std::isnan(y)) || x == y)
          << suffix << " pixel " << i << ": " << x << " vs scalar " << y;
      finite += !std::isnan(x);
    }
    EXPECT_GT(finite, 100) << suffix;
  }
  const cv::Mat tf_simd = cv::imread((dir / "simd" / (stem + "_tf.png")).string());
  const cv::Mat tf_scalar = cv::imread((dir / "scalar" / (stem + "_tf.png")).string());
  ASSERT_FALSE(tf_simd.empty());
  ASSERT_EQ(tf_simd.size(), tf_scalar.size());
  EXPECT_EQ(cv::norm(tf_simd, tf_scalar, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace lifmcr
