// bench_depth_bias: the systematic error of processing/'s virtual depth on
// synthetic frames, against the renderer's own per-pixel truth
// (GroundTruth/depth/*_virtual_depth.tiff), and what it does to a
// calibration. Each frame is processed with the TRUE intrinsics (lambda and
// principal point of GroundTruth/cameras.yaml), so the comparison needs no
// conversion between geometries. Pixels: searched (textured) estimates whose
// truth is one surface within +-2 px (no depth edge).
// Prints the signed median relative error by virtual depth bin, per lens
// type and per radius in the micro image (inside 0.4 r, 0.4-0.7 r, beyond),
// then a least-squares fit of the relative error e(v) = a / v + eps, i.e.
// v_measured = a + (1 + eps) v. In v = (b_L - b_L0) / B that is exactly
// B / (1 + eps) and b_L0 - a B: a calibration fitting these depths (the
// lateral image pins b_L0 and f_L) is pulled to B by about -eps. Baseline
// measured in the same run: the median |relative error| (the noise); the
// ratio says how far the v-dependent part (bias at v 2.5-3 minus bias at
// v 4-5) stands out of it.
//   bench_depth_bias SEQUENCE_DIR FRAME [FRAME...]

#include "bench/bench_usage.h"
#include "processing/camera_model.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/sequence.h"
#include "replay/synth/gt_images.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

using namespace lifmcr;
namespace fs = std::filesystem;

namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

constexpr std::array<double, 7> kBins = {2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0};
constexpr int kBinCount = static_cast<int>(kBins.size()) - 1;
constexpr int kBin4To5 = 3;  // the bin v 4-5 of the printed spread

int BinOf(double v) {
  for (int b = 0; b < kBinCount; ++b)
    if (v >= kBins[b] && v < kBins[b + 1]) return b;
  return -1;
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_depth_bias [--cross-type-px X] [--edge-px N] [--equalise-defocus 0|1]\n"
    "    [--smooth-radius N] [--min-support N] [--search-stride N] [--fill-min-support N]\n"
    "    [--other-surface] SEQUENCE_DIR FRAME [FRAME...]\n"
    "--cross-type-px: processing::DepthOptions::cross_type_px (the model error of a pair of\n"
    "lens types; large: the same type's ring-2 pairs carry the fused depth).\n"
    "--edge-px: pixels with a depth edge (truth beyond 1 %) within N px left out (2).\n"
    "--smooth-radius, --min-support, --search-stride, --fill-min-support: the DepthOptions\n"
    "fields (step 4's window and support, the searched lattice, step 5; 0 0 1 0 with\n"
    "--min-support 1: the search's own estimates).\n"
    "--other-surface: the pixels beyond 5 % by whether the truth within 8 px holds another\n"
    "surface, and where their estimate lies between the two.\n"
    "The systematic error of processing/'s virtual depth on frames of a synthetic sequence\n"
    "(written by `lifmcr synth`) against the renderer's per-pixel truth, by virtual depth,\n"
    "lens type and radius in the micro image, and the fit v_measured = a + (1 + eps) v.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  processing::DepthOptions depth_options;
  int first = 1;
  int edge_px = 2;  // pixels within this of a depth edge (truth) are left out
  bool other_surface = false;  // the pixels beyond 5 % by the other surface near them
  // The DepthOptions given as integers: flag and field.
  const std::array<std::pair<const char*, int*>, 4> int_options = {{
      {"--smooth-radius", &depth_options.smooth_radius_px},
      {"--min-support", &depth_options.min_support},
      {"--search-stride", &depth_options.search_stride},
      {"--fill-min-support", &depth_options.fill_min_support},
  }};
  for (;;) {
    const auto int_option = std::find_if(int_options.begin(), int_options.end(), [&](const auto& o) {
      return argc > first + 1 && std::string(argv[first]) == o.first;
    });
    if (int_option != int_options.end()) {
      *int_option->second = std::atoi(argv[first + 1]);
      first += 2;
    } else if (argc > first + 1 && std::string(argv[first]) == "--cross-type-px") {
      depth_options.cross_type_px = std::atof(argv[first + 1]);
      first += 2;
    } else if (argc > first + 1 && std::string(argv[first]) == "--edge-px") {
      edge_px = std::max(1, std::atoi(argv[first + 1]));
      first += 2;
    } else if (argc > first && std::string(argv[first]) == "--other-surface") {
      other_surface = true;
      first += 1;
    } else if (argc > first + 1 && std::string(argv[first]) == "--equalise-defocus") {
      depth_options.equalise_defocus = std::atoi(argv[first + 1]) != 0;
      first += 2;
    } else {
      break;
    }
  }
  if (argc < first + 2 || !depth_options.Check()) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  const fs::path seq = argv[first];
  std::string serial;
  for (const auto& e : fs::directory_iterator(seq))
    if (auto s = layout::ParseCameraFolderName(e.path().filename().string())) serial = *s;
  Expected<registration::CameraCalibration> truth =
      registration::ReadCameraCalibration(layout::CamerasYamlPath(seq), serial);
  if (!truth) return std::fprintf(stderr, "%s\n", truth.error().message.c_str()), 1;
  const processing::CameraModel model(truth->intrinsics);
  Expected<CameraFolder> folder = DiscoverCameraFolder(layout::CameraDir(seq, serial));
  const std::optional<fs::path> calib = FindCalibrationFor(seq);
  if (!folder || !calib) return std::fprintf(stderr, "%s: not a sequence\n", argv[first]), 1;
  Expected<MlaCalibration> mla = ReadMlaXml(layout::MlaXmlPath(*calib, serial));
  Expected<OwnedImage> white = ReadBmp(layout::WhiteImagePath(*calib, serial, 0));
  if (!mla || !white) return std::fprintf(stderr, "no MLA file or white image\n"), 1;

  // [bin][type][radius class]
  std::vector<double> errors[kBinCount][3][3];
  std::vector<double> all_abs;
  Eigen::Matrix2d ata = Eigen::Matrix2d::Zero();
  Eigen::Vector2d atb = Eigen::Vector2d::Zero();
  // The same fit over the pixels within 2 % of the truth (the tails left out).
  Eigen::Matrix2d ata_core = Eigen::Matrix2d::Zero();
  Eigen::Vector2d atb_core = Eigen::Vector2d::Zero();
  std::vector<double> sum_bin(kBinCount, 0.0);
  std::vector<long long> n_bin(kBinCount, 0), n_high(kBinCount, 0), n_low(kBinCount, 0);
  constexpr std::array<double, 5> kTail = {0.02, 0.05, 0.1, 0.3, 1e9};
  std::vector<std::array<long long, 8>> tail(kBinCount, std::array<long long, 8>{});
  processing::PlenopticFrame f;
  processing::VirtualDepthMap depth;
  long long near_other[2][3] = {}, near_frac[2][8] = {};  // [error > 0][...]
  for (int a = first + 1; a < argc; ++a) {
    const int n = std::atoi(argv[a]);
    const std::optional<fs::path> path = folder->FramePath(n);
    if (!path) return std::fprintf(stderr, "no frame %d\n", n), 1;
    Expected<OwnedImage> raw = ReadBmp(*path);
    if (!raw) return std::fprintf(stderr, "%s\n", raw.error().message.c_str()), 1;
    const processing::MlaGrid grid =
        processing::MlaGrid::FromCalibration(*mla, raw->width, raw->height);
    processing::FrameOptions options;
    options.lambda = model.lambda();
    options.principal_point_px = truth->intrinsics.PrincipalPointPx();
    if (Status s = processing::PrepareFrame(raw->View(), white->View(), grid, *mla, options, &f); !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    if (Status s = processing::EstimateVirtualDepth(f, *mla, depth_options, &depth); !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    int w = 0, h = 0;
    Expected<std::vector<float>> gt =
        synth::ReadFloatTiff(layout::VirtualDepthPath(seq, serial, n), &w, &h);
    if (!gt || w != f.width || h != f.height)
      return std::fprintf(stderr, "frame %d: no per-pixel virtual depth truth\n", n), 1;
    auto truth_at = [&](int x, int y) { return static_cast<double>((*gt)[static_cast<std::size_t>(y) * w + x]); };
    for (int y = edge_px; y < h - edge_px; ++y)
      for (int x = edge_px; x < w - edge_px; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        const int k = f.lens_of_pixel[i];
        const double v = depth.virtual_depth[i], vt = truth_at(x, y);
        if (k < 0 || !depth.textured[i] || std::isnan(v) || std::isnan(vt)) continue;
        double lo = vt, hi = vt;
        for (int dy = -edge_px; dy <= edge_px; ++dy)
          for (int dx = -edge_px; dx <= edge_px; ++dx) {
            const double q = truth_at(x + dx, y + dy);
            if (!std::isnan(q)) lo = std::min(lo, q), hi = std::max(hi, q);
          }
        if (hi > 1.01 * lo) continue;  // a depth edge
        const int b = BinOf(vt);
        if (b < 0) continue;
        const double e = v / vt - 1;
        if (other_surface && std::abs(e) > 0.05) {
          // The other surface within 8 px: the truth farthest from vt; where
          // the estimate lies between the two surfaces (a mixture) or
          // beyond (a wrong match).
          double far = vt;
          for (int dy = -8; dy <= 8; ++dy)
            for (int dx = -8; dx <= 8; ++dx) {
              if (y + dy < 0 || y + dy >= h || x + dx < 0 || x + dx >= w) continue;
              const double q = truth_at(x + dx, y + dy);
              if (!std::isnan(q) && std::abs(q - vt) > std::abs(far - vt)) far = q;
            }
          ++near_other[e > 0][far > 1.02 * vt ? 0 : far < 0.98 * vt ? 1 : 2];
          if (std::abs(far - vt) > 0.02 * vt) {
            const double frac = (v - vt) / (far - vt);
            ++near_frac[e > 0][std::clamp(static_cast<int>(std::floor(frac * 5)), -1, 6) + 1];
          }
        }
        const double r = (Eigen::Vector2d(x, y) - f.lenses[k].centre_px).norm() / f.radius_px;
        errors[b][f.lenses[k].type][r < 0.4 ? 0 : r < 0.7 ? 1 : 2].push_back(e);
        all_abs.push_back(std::abs(e));
        const Eigen::Vector2d row(1 / vt, 1);
        ata += row * row.transpose();
        atb += row * e;
        sum_bin[b] += e;
        ++n_bin[b];
        n_high[b] += e > 0.02;
        n_low[b] += e < -0.02;
        for (int q = 0; q + 1 < static_cast<int>(kTail.size()); ++q) {
          if (e >= kTail[q] && e < kTail[q + 1]) ++tail[b][4 + q];
          if (-e >= kTail[q] && -e < kTail[q + 1]) ++tail[b][3 - q];
        }
        if (std::abs(e) < 0.02) {
          ata_core += row * row.transpose();
          atb_core += row * e;
        }
      }
  }
  std::printf("signed median relative error of the virtual depth (%%, pixels): per lens type, "
              "radius in the micro image < 0.4 r / 0.4-0.7 r / > 0.7 r\n");
  std::vector<double> by_bin[kBinCount];
  for (int b = 0; b < kBinCount; ++b) {
    std::printf("  v %.1f-%.1f", kBins[b], kBins[b + 1]);
    for (int t = 0; t < 3; ++t) {
      std::printf(" | type %d", t);
      for (int r = 0; r < 3; ++r) {
        std::printf(" %+.3f (%zu)", 100 * Median(errors[b][t][r]), errors[b][t][r].size());
        by_bin[b].insert(by_bin[b].end(), errors[b][t][r].begin(), errors[b][t][r].end());
      }
    }
    std::printf(" | mean %+.3f, beyond +-2 %%: %.2f %% above, %.2f %% below\n",
                n_bin[b] ? 100 * sum_bin[b] / n_bin[b] : std::nan(""),
                n_bin[b] ? 100.0 * n_high[b] / n_bin[b] : 0.0, n_bin[b] ? 100.0 * n_low[b] / n_bin[b] : 0.0);
  }
  std::printf("tails (%% of the bin's pixels): error < -30, -30..-10, -10..-5, -5..-2 | +2..+5, "
              "+5..+10, +10..+30, > +30 %%\n");
  for (int b = 0; b < kBinCount; ++b) {
    if (n_bin[b] == 0) continue;
    std::printf("  v %.1f-%.1f", kBins[b], kBins[b + 1]);
    for (int q = 0; q < 8; ++q)
      std::printf("%s %.2f", q == 4 ? " |" : "", 100.0 * tail[b][q] / n_bin[b]);
    std::printf("\n");
  }
  if (other_surface)
    for (int sgn = 0; sgn < 2; ++sgn) {
      std::printf("pixels with error %s 5 %%: the truth within 8 px holds a nearer surface (larger "
                  "v, beyond 2 %%) %lld, a farther one %lld, none %lld; where one does, "
                  "(v - v_true) / (v_other - v_true) < 0, 0-.2, .2-.4, .4-.6, .6-.8, .8-1, 1-1.2, "
                  "> 1.2:",
                  sgn ? "above +" : "below -", near_other[sgn][0], near_other[sgn][1], near_other[sgn][2]);
      for (int q = 0; q < 8; ++q) std::printf(" %lld", near_frac[sgn][q]);
      std::printf("\n");
    }
  const Eigen::Vector2d core = ata_core.ldlt().solve(atb_core);
  std::printf("fit over the pixels within 2 %% of the truth: v_measured = %.4f + (1 %+.5f) v "
              "(B %+.2f %%)\n", core.x(), core.y(), 100 * (1 / (1 + core.y()) - 1));
  const Eigen::Vector2d fit = ata.ldlt().solve(atb);  // (a, eps)
  const double spread = Median(by_bin[0]) - Median(by_bin[kBin4To5]);
  const double noise = Median(all_abs);
  std::printf("fit v_measured = %.4f + (1 %+.5f) v: a calibration on these depths is pulled to "
              "B %+.2f %%, b_L0 %+.3f %% (B %.4f mm, b_L0 %.4f mm)\n",
              fit.x(), fit.y(), 100 * (1 / (1 + fit.y()) - 1),
              -100 * fit.x() * truth->intrinsics.mla_to_sensor_mm /
                  truth->intrinsics.mla_to_main_lens_mm,
              truth->intrinsics.mla_to_sensor_mm, truth->intrinsics.mla_to_main_lens_mm);
  std::printf("v-dependent bias (v 2.5-3 minus v 4-5) %+.3f %%, baseline median |error| %.3f %% "
              "(%zu pixels): ratio %.2f\n",
              100 * spread, 100 * noise, all_abs.size(), spread / noise);
  return 0;
}
