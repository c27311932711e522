// MLA grid from synthetic white images: centres within 0.05 px RMS of the
// truth, lens types as the generator's.

#include "processing/grid_from_raw.h"
#include "processing/mla_grid.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>

#include <cmath>

namespace lifmcr::processing {
namespace {

// RMS distance between the fitted lattice and the true micro-image centres
// over the lenses inside the image; counts lens-type disagreements.
void CompareWithTruth(const synth::PlenopticModel& truth, const MlaGrid& grid, double* rms_px,
                      int* type_errors, int* lenses) {
  double sum2 = 0;
  int n = 0, wrong = 0;
  const int w = truth.width(), h = truth.height();
  for (int j = -80; j <= 80; ++j)
    for (int i = -120; i <= 120; ++i) {
      const synth::MicroLens lens = truth.Lens(i, j);
      const Eigen::Vector2d c = lens.center_px;
      if (c.x() < 8 || c.y() < 8 || c.x() > w - 9 || c.y() > h - 9) continue;
      int fi = 0, fj = 0;
      grid.Nearest(c, &fi, &fj);
      sum2 += (grid.Center(fi, fj) - c).squaredNorm();
      if (grid.Type(fi, fj) != lens.type) ++wrong;
      ++n;
    }
  *rms_px = std::sqrt(sum2 / n);
  *type_errors = wrong;
  *lenses = n;
}

struct WhiteCase {
  double rotation_rad;
  Eigen::Vector2d offset_px;
};

class GridFit : public ::testing::TestWithParam<WhiteCase> {};

TEST_P(GridFit, CentresWithinFiveHundredthsOfAPixel) {
  synth::SynthCameraParams p = synth::MakePreset("small")->camera;
  p.mla_rotation_rad = GetParam().rotation_rad;
  p.mla_offset_px = GetParam().offset_px;
  const synth::PlenopticModel truth(p);
  const synth::RawFrame white =
      synth::RenderRaw(truth, synth::MakeWhiteScene(), Pose::Identity(), synth::RenderOptions{});

  // Without an MLA file.
  Expected<GridFitResult> blind = FitGridToWhiteImage(white.View(), nullptr);
  ASSERT_TRUE(blind.ok()) << blind.error().message;
  double rms = 0;
  int type_errors = 0, lenses = 0;
  CompareWithTruth(truth, blind->grid, &rms, &type_errors, &lenses);
  EXPECT_LT(rms, 0.05) << blind->BriefReport();
  EXPECT_GT(lenses, 2000);
  EXPECT_LT(blind->rms_px, 0.2);

  // With a slightly wrong MLA file: refined, types from the file.
  MlaCalibration file = truth.ToMlaCalibration();
  file.offset_px += Eigen::Vector2d(0.6, -0.4);
  file.diameter_px *= 1.001;
  file.rotation_rad += 5e-4;
  const MlaGrid initial = MlaGrid::FromCalibration(file, p.width_px, p.height_px);
  double rms0 = 0;
  CompareWithTruth(truth, initial, &rms0, &type_errors, &lenses);
  EXPECT_EQ(type_errors, 0);
  EXPECT_GT(rms0, 0.3);
  Expected<GridFitResult> fit = FitGridToWhiteImage(white.View(), &initial);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  CompareWithTruth(truth, fit->grid, &rms, &type_errors, &lenses);
  EXPECT_LT(rms, 0.05) << fit->BriefReport();
  EXPECT_EQ(type_errors, 0);
  const MlaCalibration refined = fit->grid.ToCalibration(file, p.width_px, p.height_px);
  EXPECT_NEAR(refined.diameter_px, p.micro_image_pitch_px, 2e-3);
  EXPECT_NEAR(refined.rotation_rad, p.mla_rotation_rad, 2e-4);
  EXPECT_LT((refined.offset_px - p.mla_offset_px).norm(), 0.05);
  std::printf("grid fit: %s; vs truth %.4f px RMS\n", fit->BriefReport().c_str(), rms);
}

INSTANTIATE_TEST_SUITE_P(WhiteImages, GridFit,
                         ::testing::Values(WhiteCase{0.0, {0.3, -0.2}},
                                           WhiteCase{0.004, {-3.7, 5.25}}));

// No white image: the lattice from a raw image of the textured table-top
// scene, started from a slightly wrong MLA file, and without one.
TEST(GridFitTextured, RawOfATexturedSceneWithinATenthOfAPixel) {
  const testing::SynthFrame s = testing::RenderSynthFrame("small", 1.0);
  const synth::PlenopticModel& truth = *s.model;
  MlaCalibration file = s.mla;
  file.offset_px += Eigen::Vector2d(0.6, -0.4);
  file.diameter_px *= 1.001;
  file.rotation_rad += 5e-4;
  const MlaGrid initial = MlaGrid::FromCalibration(file, s.raw.width, s.raw.height);
  double rms0 = 0, rms = 0;
  int type_errors = 0, lenses = 0;
  CompareWithTruth(truth, initial, &rms0, &type_errors, &lenses);
  EXPECT_GT(rms0, 0.3);
  Expected<GridFitResult> fit = FitGridToRawImage(s.raw.View(), &initial);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  CompareWithTruth(truth, fit->grid, &rms, &type_errors, &lenses);
  std::printf("textured raw fit from a wrong MLA file (%.3f px RMS): %s; vs truth %.4f px RMS\n",
              rms0, fit->BriefReport().c_str(), rms);
  EXPECT_LT(rms, 0.1) << fit->BriefReport();
  EXPECT_EQ(type_errors, 0);
  EXPECT_GT(lenses, 2000);

  // Without an MLA file the white-image detector's first lattice is wrong
  // on this strongly textured scene: an error that says what to give, not a
  // wrong lattice.
  Expected<GridFitResult> blind = FitGridToRawImage(s.raw.View(), nullptr);
  ASSERT_FALSE(blind.ok());
  EXPECT_NE(blind.error().message.find("MLA file"), std::string::npos) << blind.error().message;
}

TEST(GridFitErrors, BlackImageIsAnError) {
  std::vector<std::uint8_t> black(200 * 100, 0);
  const ConstImageView view(black.data(), 200, 100, 200, PixelFormat::kMono8);
  Expected<GridFitResult> fit = FitGridToWhiteImage(view, nullptr);
  ASSERT_FALSE(fit.ok());
  EXPECT_NE(fit.error().message.find("too dark"), std::string::npos);
}

TEST(MlaGridFromFile, TypesFollowTheFile) {
  MlaCalibration mla;
  mla.diameter_px = 16;
  mla.lens_types[1].offset_lens = {1, 0};
  mla.lens_types[2].offset_lens = {-1, 0};
  MlaGrid grid = MlaGrid::FromCalibration(mla, 100, 100);
  EXPECT_EQ(grid.Type(1, 0), 1);
  EXPECT_EQ(grid.Type(-1, 0), 2);
  EXPECT_EQ(grid.Type(0, 1), 2);
  mla.lens_types[1].offset_lens = {-1, 0};
  mla.lens_types[2].offset_lens = {1, 0};
  grid = MlaGrid::FromCalibration(mla, 100, 100);
  EXPECT_EQ(grid.Type(-1, 0), 1);
  EXPECT_EQ(grid.Center(1, 0).x() - grid.Center(0, 0).x(), 16);
}

}  // namespace
}  // namespace lifmcr::processing
