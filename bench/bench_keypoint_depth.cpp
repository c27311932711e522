// bench_keypoint_depth: the error of the calibration keypoints' virtual
// depths against the renderer's truth, by the range of the measured virtual
// depth over the keypoint's support (registration/features/keypoint_depth.h),
// and the B a calibration on those depths is pulled to. Each frame goes
// through the calibration's frame loader (processing/, SIFT on the TF image)
// with the TRUE intrinsics, so measured and true virtual depths compare
// without a conversion between geometries. The truth: GroundTruth/depth
// (camera z on the TF grid) at the keypoint, v = VirtualDepthOfDepth(z);
// keypoints whose 2 x 2 truth holds two surfaces (1 % apart) are counted
// apart ("on a true edge") and left out of the fits.
// Per support radius and range class: the keypoints, the signed median and
// median |relative error|, the share beyond 2 %, and the least-squares fit
// e(v) = a / v + eps (v_measured = a + (1 + eps) v; a calibration on these
// depths is pulled to B by about -eps, bench_depth_bias). Then the same for
// the keypoints kept by a range limit (the calibration's rule: those above
// enter by their position only). Baseline in the same run: every keypoint.
//   bench_keypoint_depth [--serial S] SEQUENCE_DIR FRAME [FRAME...]

#include "bench/bench_usage.h"
#include "bench/truth_frames.h"
#include "processing/camera_model.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/features/keypoint_depth.h"
#include "replay/layout.h"
#include "replay/synth/gt_images.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

using namespace lifmcr;
namespace fs = std::filesystem;

namespace {

struct Sample {
  double v_true = 0, e = 0;  // e = v_measured / v_true - 1
  std::array<float, 3> range{};  // at kRadii
};
constexpr std::array<int, 3> kRadii = {2, 4, 8};

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// n, signed median, median |e|, share beyond 2 %, and the fit's a, eps.
void PrintRow(const char* label, const std::vector<const Sample*>& s, std::size_t total) {
  std::vector<double> e, a;
  Eigen::Matrix2d ata = Eigen::Matrix2d::Zero();
  Eigen::Vector2d atb = Eigen::Vector2d::Zero();
  long long far = 0;
  for (const Sample* x : s) {
    e.push_back(x->e);
    a.push_back(std::abs(x->e));
    far += std::abs(x->e) > 0.02;
    const Eigen::Vector2d row(1 / x->v_true, 1);
    ata += row * row.transpose();
    atb += row * x->e;
  }
  const Eigen::Vector2d fit =
      s.size() >= 3 ? Eigen::Vector2d(ata.ldlt().solve(atb)) : Eigen::Vector2d(NAN, NAN);
  std::printf("%-22s %7zu (%5.1f %%)  median %+.3f %%  |e| %.3f %%  >2 %% %5.1f %%  "
              "v_m = %+.4f + (1 %+.5f) v  B pull %+.2f %%\n",
              label, s.size(), 100.0 * s.size() / std::max<std::size_t>(total, 1),
              100 * Median(e), 100 * Median(a), 100.0 * far / std::max<std::size_t>(s.size(), 1),
              fit.x(), fit.y(), -100 * fit.y());
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_keypoint_depth [--serial S] SEQUENCE_DIR FRAME [FRAME...]\n"
    "The calibration keypoints' virtual-depth error against the renderer's truth (frames\n"
    "processed with the true intrinsics), by the range of the measured virtual depth over\n"
    "the keypoint's support (radius 2, 4, 8 TF px), with the fit v_measured = a + (1 + eps) v\n"
    "and the B it pulls a calibration to; baseline: every keypoint.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  bench::TruthFrames truth_frames;
  if (const int code = bench::OpenTruthFrames(argc, argv, kUsage, &truth_frames)) return code;
  const fs::path& seq = truth_frames.seq;
  const std::string& serial = truth_frames.serial;
  const int first = truth_frames.first;
  const processing::CameraModel& model = *truth_frames.model;
  std::unique_ptr<registration::CalibrationFrameLoader>* loader = &truth_frames.loader;

  std::vector<Sample> samples;
  long long on_true_edge = 0, without = 0;
  for (int a = first + 1; a < argc; ++a) {
    const int n = std::atoi(argv[a]);
    Expected<registration::CalibrationFrame> frame = (*loader)->Load(n);
    if (!frame) return std::fprintf(stderr, "%s\n", frame.error().message.c_str()), 1;
    int w = 0, h = 0;
    Expected<std::vector<float>> z_mm =
        synth::ReadFloatTiff(layout::DepthMmPath(seq, serial, n), &w, &h);
    if (!z_mm || w != frame->tf_width || h != frame->tf_height)
      return std::fprintf(stderr, "frame %d: no depth truth on the TF grid\n", n), 1;
    const std::vector<float>& tf_depth = (*loader)->last_tf_virtual_depth();
    auto z_at = [&](int x, int y) {
      return static_cast<double>(
          (*z_mm)[static_cast<std::size_t>(std::clamp(y, 0, h - 1)) * w + std::clamp(x, 0, w - 1)]);
    };
    for (std::size_t k = 0; k < frame->features.keypoints.size(); ++k) {
      const Eigen::Vector2f p = frame->features.keypoints[k].xy_px;
      const double v = frame->virtual_depth[k];
      const int x0 = static_cast<int>(std::floor(p.x())), y0 = static_cast<int>(std::floor(p.y()));
      const double z00 = z_at(x0, y0), z10 = z_at(x0 + 1, y0), z01 = z_at(x0, y0 + 1),
                   z11 = z_at(x0 + 1, y0 + 1);
      const double lo = std::min({z00, z10, z01, z11}), hi = std::max({z00, z10, z01, z11});
      if (std::isnan(v) || !(lo > 0)) {
        ++without;
        continue;
      }
      if (!(hi <= 1.01 * lo)) {
        ++on_true_edge;
        continue;
      }
      const double z = z_at(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
      Sample s;
      s.v_true = model.VirtualDepthOfDepth(z);
      s.e = v / s.v_true - 1;
      for (std::size_t r = 0; r < kRadii.size(); ++r)
        s.range[r] = registration::VirtualDepthRange(tf_depth, w, h, p, kRadii[r]);
      samples.push_back(s);
    }
    std::fprintf(stderr, "frame %d: %zu keypoints\n", n, frame->features.keypoints.size());
  }
  std::printf("%zu keypoints on one true surface (%lld on a true edge, %lld without depth)\n",
              samples.size(), on_true_edge, without);
  std::vector<const Sample*> all;
  for (const Sample& s : samples) all.push_back(&s);
  PrintRow("every keypoint", all, samples.size());
  constexpr std::array<double, 6> kClass = {0, 0.01, 0.02, 0.03, 0.05, 1e9};
  for (std::size_t r = 0; r < kRadii.size(); ++r) {
    std::printf("support radius %d TF px, by range:\n", kRadii[r]);
    for (std::size_t c = 0; c + 1 < kClass.size(); ++c) {
      std::vector<const Sample*> in;
      for (const Sample& s : samples)
        if (s.range[r] >= kClass[c] && s.range[r] < kClass[c + 1]) in.push_back(&s);
      char label[64];
      std::snprintf(label, sizeof(label), "  range %.0f-%.0f %%", 100 * kClass[c],
                    std::min(100 * kClass[c + 1], 999.0));
      PrintRow(label, in, samples.size());
    }
    std::vector<const Sample*> unknown;
    for (const Sample& s : samples)
      if (std::isnan(s.range[r])) unknown.push_back(&s);
    PrintRow("  range unknown", unknown, samples.size());
    for (const double limit : {0.01, 0.015, 0.02, 0.03, 0.05}) {
      std::vector<const Sample*> kept;
      for (const Sample& s : samples)
        if (s.range[r] <= limit) kept.push_back(&s);
      char label[64];
      std::snprintf(label, sizeof(label), "  kept range <= %.1f %%", 100 * limit);
      PrintRow(label, kept, samples.size());
    }
  }
  return 0;
}
