// bench_keypoint_position: where the calibration's SIFT keypoints sit against
// the truth, in two parts that add up to the keypoint's offset from the
// projection of its true point:
//  - the detector's own convention (DetectSift, registration/features/
//    features.h): SIFT on the TF image and on the same image turned by 180°.
//    A feature at x is at W - 1 - x in the turned image, so a detector that
//    reports x + b reports W - 1 - x + b there: b = (r + r' - (W - 1)) / 2
//    over the pairs found at both (per axis, by SIFT octave);
//  - the TF image's shift against the renderer's all-in-focus image (the same
//    TF grid, each pixel the scene point on its ray, replay/synth/renderer.h):
//    the same detector on both, the pairs within 1 px, the median difference
//    (the detector's offset cancels).
// Frames go through the calibration's frame loader with the true intrinsics.
// Baseline in the same run: the offset OpenCV's own keypoints carry (the
// positions before DetectSift's correction, b + 1/4).
//   bench_keypoint_position [--serial S] SEQUENCE_DIR FRAME [FRAME...]

#include "bench/bench_usage.h"
#include "bench/truth_frames.h"
#include "processing/camera_model.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/detector_offset.h"
#include "registration/features/features.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/layout.h"
#include "replay/synth/synth_writer.h"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

using namespace lifmcr;
namespace fs = std::filesystem;

namespace {

constexpr char kUsage[] =
    "usage: bench_keypoint_position [--serial S] SEQUENCE_DIR FRAME [FRAME...]\n"
    "The calibration keypoints' position against the truth (frames processed with the true\n"
    "intrinsics): the detector's offset (SIFT on the TF image and on it turned by 180 deg) and\n"
    "the TF image's shift against the renderer's all-in-focus image, per axis, in TF px.\n";

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}
double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? std::nan("") : s / v.size();
}

int OctaveOf(const registration::Keypoint& k) {
  return static_cast<int>(static_cast<signed char>(k.octave & 0xff));
}

// For each keypoint of `a`, the index of the keypoint of `b` (positions
// already in a's frame, `b_xy`) within `radius` px and 20 % of its size,
// nearest; -1 where none.
struct Offsets {
  std::vector<double> x, y;
};

void Print(const char* label, const Offsets& o) {
  std::printf("%-34s %6zu pairs  x median %+.4f mean %+.4f  y median %+.4f mean %+.4f TF px\n",
              label, o.x.size(), Median(o.x), Mean(o.x), Median(o.y), Mean(o.y));
}

}  // namespace

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  bench::TruthFrames truth_frames;
  if (const int code = bench::OpenTruthFrames(argc, argv, kUsage, &truth_frames)) return code;
  const fs::path& seq = truth_frames.seq;
  const std::string& serial = truth_frames.serial;
  const int first = truth_frames.first;
  const registration::FrameLoaderOptions& options = truth_frames.options;
  std::unique_ptr<registration::CalibrationFrameLoader>* loader = &truth_frames.loader;

  std::map<int, Offsets> detector;  // by octave
  Offsets detector_all, tf_shift;
  for (int a = first + 1; a < argc; ++a) {
    const int n = std::atoi(argv[a]);
    Expected<registration::CalibrationFrame> frame = (*loader)->Load(n);
    if (!frame) return std::fprintf(stderr, "%s\n", frame.error().message.c_str()), 1;
    const ConstImageView tf = (*loader)->last_tf_image();
    Expected<std::vector<registration::DetectorOffset>> offsets =
        registration::DetectorOffsetsByTurning(tf, frame->features, options.features);
    if (!offsets) return std::fprintf(stderr, "%s\n", offsets.error().message.c_str()), 1;
    for (const registration::DetectorOffset& d : *offsets) {
      Offsets& o = detector[OctaveOf(frame->features.keypoints[d.keypoint])];
      o.x.push_back(d.offset_px.x());
      o.y.push_back(d.offset_px.y());
      detector_all.x.push_back(d.offset_px.x());
      detector_all.y.push_back(d.offset_px.y());
    }
    const cv::Mat aif = cv::imread(synth::AllInFocusPath(seq, serial, n).string(),
                                   cv::IMREAD_GRAYSCALE);
    if (aif.empty() || aif.cols != tf.width || aif.rows != tf.height)
      return std::fprintf(stderr, "frame %d: no all-in-focus truth on the TF grid\n", n), 1;
    registration::Features on_truth;
    if (Status s = registration::DetectSift(
            ConstImageView(aif.data, aif.cols, aif.rows, aif.step, PixelFormat::kMono8),
            options.features, &on_truth);
        !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    std::vector<Eigen::Vector2f> truth_xy;
    for (const auto& k : on_truth.keypoints) truth_xy.push_back(k.xy_px);
    const std::vector<int> matched =
        registration::PairByPosition(frame->features, truth_xy, on_truth, 1.0f);
    for (std::size_t i = 0; i < matched.size(); ++i) {
      if (matched[i] < 0) continue;
      const Eigen::Vector2f d =
          frame->features.keypoints[i].xy_px - on_truth.keypoints[matched[i]].xy_px;
      tf_shift.x.push_back(d.x());
      tf_shift.y.push_back(d.y());
    }
    std::fprintf(stderr, "frame %d: %zu keypoints, %zu paired on the turned image, %zu on the truth\n",
                 n, frame->features.keypoints.size(), offsets->size(), on_truth.keypoints.size());
  }
  std::printf("detector offset b (DetectSift against the feature's own position):\n");
  Print("  every octave", detector_all);
  for (const auto& [octave, o] : detector) {
    char label[64];
    std::snprintf(label, sizeof(label), "  octave %+d", octave);
    Print(label, o);
  }
  Offsets opencv = detector_all;
  for (double& x : opencv.x) x += registration::kSiftOffsetCorrectedPx;
  for (double& y : opencv.y) y += registration::kSiftOffsetCorrectedPx;
  Print("  baseline: OpenCV's own positions", opencv);
  std::printf("TF image against the all-in-focus truth (same detector on both):\n");
  Print("  TF - truth", tf_shift);
  std::printf("keypoint against the truth (detector + TF image): x %+.4f y %+.4f TF px "
              "(OpenCV's own: x %+.4f y %+.4f)\n",
              Median(detector_all.x) + Median(tf_shift.x), Median(detector_all.y) + Median(tf_shift.y),
              Median(opencv.x) + Median(tf_shift.x), Median(opencv.y) + Median(tf_shift.y));
  return 0;
}
