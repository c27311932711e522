// bench_depth: processing/ on one synthetic frame (default the r32 preset,
// 6560x4948), on all cores (run under `taskset -c 0,1` for the 2-core figure):
//   - grid fit to the white image (seconds, median),
//   - virtual depth: raw MP/s (per-frame prepare + estimate, median of runs;
//     the per-camera devignetting gain and micro-image map are made once), with the
//     accuracy gates measured on that frame against the ground truth, for the
//     full search and the search seeded by the per-lens depth (its time
//     included), each on the scalar and the SIMD kernels, beside a
//     naive reference measured in the same run: brute-force block matching
//     (5x5 SSD summed over all six first-ring neighbours, every disparity step
//     of 0.5 px over the MLA file's depth range, every valid pixel) on a crop;
//   - per-lens virtual depth (processing/lens_depth.h): ms per frame
//     (median of runs), with the dense search over the same frame as the
//     baseline of the same run; accuracy against the ground truth reduced
//     per micro image (its median): coverage of the textured lenses, median
//     |dv|/v, outliers, beside the dense map reduced the same way; and the
//     TF preview at each lens's depth (512 px) with its RMS and PSNR against
//     the all-in-focus ground truth (rendered once, not timed);
//   - TF image: output MP/s (TF depth + rendering), beside the same on one
//     thread and a naive renderer (every micro image that sees the point,
//     averaged) on a crop of the TF grid.
//   The load average is printed with the figures.
//   bench_depth [--preset r32|medium|small] [--scene table|plain] [--scene-seed N]
//               [--repeat N] [--crop PX]
//               [--stride 0|1|2] [--ring1 1..6] [--ring2 0..6] [--type-ranges 0|1] (DepthOptions)
//               [--lens-only 1] (dense baseline and per-lens depth only: no grid fit, naive
//               references or TF) [--dense 0] (with --lens-only 1: no dense baseline)
//               [--lens-path scalar|simd|both] [--lens-samples N] [--lens-previous 0|1]
//               (1: each per-lens run seeded by the run before's map, the temporal seed of
//               a camera that did not move: its best case) [--lens-neighbours 0|1]
//               (LensDepthOptions::neighbour_seed; 0, the default: every lens searched
//               from nothing) [--lens-step PX] [--lens-fraction F] [--lens-rings 1|2]
//               [--lens-enough N] (LensDepthOptions' candidate_step_px, candidate_fraction,
//               rings, enough_estimates)
//               [--seed full|seeded|both] [--dense-path scalar|simd|both] [--seed-margin PX]
//               [--seed-ring1 1..6] [--seed-ring2 0..6] [--seed-cost-ratio R] [--seed-stride 0..8]
//               [--seed-ring2-lines 0|1|3] [--seed-interp-spread R] (DepthOptions)
//               [--dense-for-tf 0|1] (1: the seeded map only where the TF depth map reads
//               it, the live chain's ChainOptions::dense_for_tf_only)

#include "bench/bench_usage.h"
#include "processing/camera_model.h"
#include "processing/lens_depth.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/total_focus.h"
#include "processing/virtual_depth.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

// Under callgrind the per-lens runs alone are instrumented (valgrind
// --instr-atstart=no: the gain map, the truth and the rest run at valgrind's
// bare speed, a `r32` run in 2 minutes instead of 7); a no-op elsewhere.
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#else
#define CALLGRIND_START_INSTRUMENTATION do {} while (0)
#define CALLGRIND_STOP_INSTRUMENTATION do {} while (0)
#endif

using namespace lifmcr;
using namespace lifmcr::processing;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double ProcessCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

std::string LoadAverage() {
  double load[3] = {0, 0, 0};
  if (getloadavg(load, 3) != 3) return "load average unknown";
  char buf[96];
  std::snprintf(buf, sizeof buf, "load average %.2f %.2f %.2f", load[0], load[1], load[2]);
  return buf;
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");  // a figure not measured (--tf-baseline 0)
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Naive reference: for every valid pixel of the crop, every disparity step,
// the 5x5 SSD summed over the six first-ring neighbours; the best step wins.
// Returns the pixels processed.
long long NaiveBlockMatching(const PlenopticFrame& f, const MlaCalibration& mla, int x0, int y0,
                             int size, std::vector<float>* out) {
  double z_lo = 1, z_hi = 0;
  for (const MlaLensType& t : mla.lens_types) {
    z_lo = std::min(z_lo, 1.0 / std::max(1.05, t.depth_max));
    z_hi = std::max(z_hi, 1.0 / std::max(1.05, t.depth_min));
  }
  const int ring[6][2] = {{1, 0}, {0, 1}, {-1, 1}, {-1, 0}, {0, -1}, {1, -1}};
  long long pixels = 0;
  out->assign(static_cast<std::size_t>(size) * size, NAN);
  for (int y = y0; y < y0 + size; ++y)
    for (int x = x0; x < x0 + size; ++x) {
      const int k = f.lens_of_pixel[static_cast<std::size_t>(y) * f.width + x];
      if (k < 0) continue;
      ++pixels;
      const MicroImage& m = f.lenses[k];
      const double pitch = f.grid.PitchPx();
      const double dz = 0.5 / (f.lambda * pitch);
      double best = 1e300, best_z = NAN;
      for (double z = z_lo; z <= z_hi; z += dz) {
        double cost = 0;
        int used = 0;
        for (const auto& d : ring) {
          const int n = f.LensAt(m.i + d[0], m.j + d[1]);
          if (n < 0) continue;
          const Eigen::Vector2d delta = f.lenses[n].centre_px - m.centre_px;
          const Eigen::Vector2d q = Eigen::Vector2d(x, y) + f.lambda * delta * (1 - z);
          double c = 0;
          bool ok = true;
          for (int b = -2; b <= 2 && ok; ++b)
            for (int a = -2; a <= 2; ++a) {
              const float s0 = f.SampleGrey(x + a, y + b);
              const float s1 = f.SampleGrey(q.x() + a, q.y() + b);
              if (std::isnan(s0) || std::isnan(s1)) {
                ok = false;
                break;
              }
              c += (s0 - s1) * (s0 - s1);
            }
          if (!ok) continue;
          cost += c;
          ++used;
        }
        if (used > 0 && cost / used < best) {
          best = cost / used;
          best_z = z;
        }
      }
      (*out)[static_cast<std::size_t>(y - y0) * size + (x - x0)] = static_cast<float>(1 / best_z);
    }
  return pixels;
}

// Naive TF reference: for every TF pixel of a crop, every micro image of
// the hexagonal neighbourhood that can see the virtual point (reach v r / D
// lenses) is sampled (bilinear, devignetted) at p = l + (x - l) / v and the
// valid samples are averaged; v from the same TF depth map. Returns the
// pixels rendered.
long long NaiveTotalFocus(const PlenopticFrame& f, const TfDepthMap& depth, int u0, int w0,
                          int size, std::vector<float>* out) {
  const int channels = f.has_colour ? 3 : 1;
  out->assign(static_cast<std::size_t>(size) * size * channels, 0.0f);
  const double pitch = f.grid.PitchPx(), r2 = f.radius_px * f.radius_px;
  long long pixels = 0;
  for (int w = w0; w < w0 + size; ++w)
    for (int u = u0; u < u0 + size; ++u) {
      double v = depth.virtual_depth[static_cast<std::size_t>(w) * depth.width + u];
      if (!(v > 1)) v = depth.fallback_v > 1 ? depth.fallback_v : 3.0;
      const Eigen::Vector2d x(2.0 * u + 0.5, 2.0 * w + 0.5);
      int i0 = 0, j0 = 0;
      f.grid.Nearest(x, &i0, &j0);
      const int reach = static_cast<int>(std::ceil(v * f.radius_px / pitch)) + 1;
      double acc[3] = {0, 0, 0};
      int n = 0;
      for (int dj = -reach; dj <= reach; ++dj)
        for (int di = -reach; di <= reach; ++di) {
          const int k = f.LensAt(i0 + di, j0 + dj);
          if (k < 0) continue;
          const MicroImage& m = f.lenses[k];
          const Eigen::Vector2d p = m.lens_px + (x - m.lens_px) / v;
          if ((p - m.centre_px).squaredNorm() > r2) continue;
          const int px = static_cast<int>(p.x()), py = static_cast<int>(p.y());
          if (p.x() < 0 || p.y() < 0 || px >= f.width - 1 || py >= f.height - 1) continue;
          const double fx = p.x() - px, fy = p.y() - py;
          double sample[3] = {0, 0, 0};
          bool ok = true;
          for (int q = 0; q < 4 && ok; ++q) {
            const int xx = px + (q & 1), yy = py + (q >> 1);
            const double wq = ((q & 1) ? fx : 1 - fx) * ((q >> 1) ? fy : 1 - fy);
            const float g = f.gain[static_cast<std::size_t>(yy) * f.width + xx];
            if (std::isnan(g)) ok = false;
            const std::uint8_t* pix = f.raw.Row(yy) + xx * channels;
            for (int c = 0; c < channels; ++c) sample[c] += wq * g * pix[c];
          }
          if (!ok) continue;
          for (int c = 0; c < channels; ++c) acc[c] += sample[c];
          ++n;
        }
      ++pixels;
      for (int c = 0; c < channels; ++c)
        (*out)[(static_cast<std::size_t>(w - w0) * size + (u - u0)) * channels + c] =
            n > 0 ? static_cast<float>(acc[c] / n) : 0.0f;
    }
  return pixels;
}

// --frames FILE: the rendered frames of one preset and scene (key), so
// repeated runs skip the renderer. Layout: the key's length and bytes, then
// per frame width, height, format, the pixel and virtual-depth byte counts
// and their bytes (this machine's byte order: a cache, not an exchange format).
bool WriteFrames(const std::string& path, const std::string& key, const synth::RawFrame& raw,
                 const synth::RawFrame& white) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) return false;
  bool ok = true;
  auto put = [&](const void* data, std::size_t bytes) {
    ok = ok && std::fwrite(data, 1, bytes, file) == bytes;
  };
  const std::uint64_t key_n = key.size();
  put(&key_n, sizeof key_n);
  put(key.data(), key.size());
  for (const synth::RawFrame* f : {&raw, &white}) {
    const std::int32_t head[3] = {f->width, f->height, static_cast<std::int32_t>(f->format)};
    const std::uint64_t n[2] = {f->pixels.size(), f->virtual_depth.size()};
    put(head, sizeof head);
    put(n, sizeof n);
    put(f->pixels.data(), f->pixels.size());
    put(f->virtual_depth.data(), f->virtual_depth.size() * sizeof(float));
  }
  return std::fclose(file) == 0 && ok;
}

bool ReadFrames(const std::string& path, const std::string& key, synth::RawFrame* raw,
                synth::RawFrame* white) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return false;
  bool ok = true;
  auto get = [&](void* data, std::size_t bytes) {
    ok = ok && std::fread(data, 1, bytes, file) == bytes;
  };
  std::uint64_t key_n = 0;
  get(&key_n, sizeof key_n);
  std::string stored(ok && key_n < 256 ? key_n : 0, ' ');
  get(stored.data(), stored.size());
  ok = ok && stored == key;
  for (synth::RawFrame* f : {raw, white}) {
    std::int32_t head[3] = {};
    std::uint64_t n[2] = {};
    get(head, sizeof head);
    get(n, sizeof n);
    ok = ok && head[0] > 0 && head[1] > 0 &&
         n[0] == static_cast<std::uint64_t>(head[0]) * head[1] *
                     BytesPerPixel(static_cast<PixelFormat>(head[2])) &&
         n[1] <= static_cast<std::uint64_t>(head[0]) * head[1];
    if (!ok) break;
    f->width = head[0];
    f->height = head[1];
    f->format = static_cast<PixelFormat>(head[2]);
    f->pixels.resize(n[0]);
    f->virtual_depth.resize(n[1]);
    get(f->pixels.data(), n[0]);
    get(f->virtual_depth.data(), n[1] * sizeof(float));
  }
  std::fclose(file);
  return ok;
}

// --tf-only MAP: the dense map's virtual depth and sigma_z (what the TF
// image reads), after the key; the same cache rules as --frames.
bool WriteDenseMap(const std::string& path, const std::string& key, const VirtualDepthMap& map) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) return false;
  const std::uint64_t key_n = key.size();
  const std::int32_t head[2] = {map.width, map.height};
  const std::size_t n = map.virtual_depth.size();
  bool ok = std::fwrite(&key_n, sizeof key_n, 1, file) == 1 &&
            std::fwrite(key.data(), 1, key.size(), file) == key.size() &&
            std::fwrite(head, sizeof head, 1, file) == 1 &&
            std::fwrite(map.virtual_depth.data(), sizeof(float), n, file) == n &&
            std::fwrite(map.sigma_z.data(), sizeof(float), n, file) == n;
  return std::fclose(file) == 0 && ok;
}

bool ReadDenseMap(const std::string& path, const std::string& key, VirtualDepthMap* map) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return false;
  std::uint64_t key_n = 0;
  std::int32_t head[2] = {};
  bool ok = std::fread(&key_n, sizeof key_n, 1, file) == 1 && key_n < 256;
  std::string stored(ok ? key_n : 0, ' ');
  ok = ok && std::fread(stored.data(), 1, stored.size(), file) == stored.size() && stored == key &&
       std::fread(head, sizeof head, 1, file) == 1 && head[0] > 0 && head[1] > 0;
  if (ok) {
    const std::size_t n = static_cast<std::size_t>(head[0]) * head[1];
    map->width = head[0];
    map->height = head[1];
    map->virtual_depth.resize(n);
    map->sigma_z.resize(n);
    ok = std::fread(map->virtual_depth.data(), sizeof(float), n, file) == n &&
         std::fread(map->sigma_z.data(), sizeof(float), n, file) == n;
  }
  std::fclose(file);
  return ok;
}

// --lens-step, --lens-fraction, --lens-rings, --lens-enough: the per-lens
// estimator's candidate grid, rings and early stop (LensDepthOptions; its
// Check() validates them); false for any other flag.
bool SetLensOption(const char* flag, const char* value, LensDepthOptions* o) {
  const std::pair<const char*, double*> reals[] = {{"--lens-step", &o->candidate_step_px},
                                                   {"--lens-fraction", &o->candidate_fraction}};
  const std::pair<const char*, int*> counts[] = {{"--lens-rings", &o->rings},
                                                 {"--lens-enough", &o->enough_estimates}};
  for (const auto& [name, field] : reals)
    if (!std::strcmp(flag, name)) return (*field = std::atof(value)), true;
  for (const auto& [name, field] : counts)
    if (!std::strcmp(flag, name)) return (*field = std::atoi(value)), true;
  return false;
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_depth [--preset r32|medium|small] [--scene table|plain] [--scene-seed N]\n"
    "                   [--repeat N]\n"
    "                   [--crop PX] [--stride 0|1|2] [--ring1 1..6] [--ring2 0..6]\n"
    "                   [--type-ranges 0|1] [--lens-only 1] [--dense 0|1]\n"
    "                   [--lens-path scalar|simd|both] [--lens-samples N]\n"
    "                   [--lens-previous 0|1] [--lens-neighbours 0|1] [--lens-grey 0|1]\n"
    "                   [--lens-step PX]\n"
    "                   [--lens-fraction F] [--lens-rings 1|2] [--lens-enough N]\n"
    "                   [--seed full|seeded|both] [--dense-path scalar|simd|both]\n"
    "                   [--seed-margin PX] [--seed-ring1 1..6] [--seed-ring2 0..6]\n"
    "                   [--seed-cost-ratio R] [--seed-stride 0..8]\n"
    "                   [--seed-ring2-lines 0|1|3] [--seed-interp-spread R]\n"
    "                   [--dense-for-tf 0|1] [--frames FILE]\n"
    "                   [--tf-only MAP] [--tf-out FILE] [--tf-baseline 0|1]\n"
    "                   [--tf-psnr 0|1]\n"
    "processing/ on one synthetic frame (default r32) on all cores: grid fit to the white\n"
    "image, virtual depth in raw MP/s with its accuracy against the ground truth (the full\n"
    "search and the search seeded by the per-lens depth, scalar and SIMD, side by side)\n"
    "beside a brute-force block matcher on a --crop, and the TF image beside one thread and\n"
    "a naive renderer. Run under `taskset -c 0,1` for the 2-core figure. --frames FILE keeps\n"
    "the rendered raw, white and true depth there (rendered and written when FILE does not\n"
    "exist, read when it holds this preset and scene; the r32 frames take 45 s to render).\n"
    "--scene-seed N renders the scene from seed N (its objects and textures) instead of the\n"
    "preset's, so a gate can be checked on another scene than the default one.\n"
    "--lens-previous 1 seeds each per-lens run by the run before's map (the temporal seed\n"
    "of a camera that did not move: its best case, not a moving camera's figure).\n"
    "--lens-neighbours 1 searches the lenses of types 1 and 2 first around their earlier-type\n"
    "neighbours' depth (LensDepthOptions::neighbour_seed; default 0: every lens from nothing).\n"
    "--lens-grey 0 reads a BGR frame's three channels in the per-lens search instead of its\n"
    "grey plane (LensDepthOptions::grey_plane; default 1).\n"
    "--lens-step, --lens-fraction, --lens-rings, --lens-enough: LensDepthOptions'\n"
    "candidate_step_px, candidate_fraction, rings and enough_estimates (the defaults: 0\n"
    "(the pitch / 11), 0.6, 2, 2); the textured lenses the coverage counts are the gate's own.\n"
    "--dense-for-tf 1: the seeded map without the micro images whose TF depth comes from\n"
    "their lens depth (the live chain's ChainOptions::dense_for_tf_only); its coverage is\n"
    "of the textured pixels of the micro images it estimates. The TF depth map's accuracy\n"
    "against the truth is printed with the TF image (--tf-psnr 1), the figure to compare.\n"
    "--tf-only MAP: the TF image alone (with its baselines), on the seeded SIMD dense map kept\n"
    "in MAP (estimated once and written when MAP does not hold this preset and scene).\n"
    "--tf-out FILE writes the TF image there (PGM or PPM) to compare two builds' images.\n"
    "--tf-baseline 0 leaves out the TF image from every dense pixel (a profile of the\n"
    "chain's way alone); --tf-psnr 0 leaves out its PSNR (the all-in-focus truth is not\n"
    "rendered: a callgrind run of the TF stage in minutes).\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string preset = "r32", scene_name = "table";
  int repeat = 3, crop = 256;
  long long scene_seed = -1;  // -1: the preset's
  DepthOptions depth_options;
  LensDepthOptions lens_options;
  bool lens_only = false, run_dense = true, lens_previous = false;
  std::string lens_path = "both", dense_path = "both", seed_mode = "both", frames_file;
  std::string tf_only_map, tf_out;
  bool tf_baseline = true, tf_psnr = true, dense_for_tf = false;
  for (int k = 1; k + 1 < argc; k += 2) {
    if (!std::strcmp(argv[k], "--preset"))
      preset = argv[k + 1];
    else if (!std::strcmp(argv[k], "--repeat"))
      repeat = std::max(1, std::atoi(argv[k + 1]));
    else if (!std::strcmp(argv[k], "--scene"))
      scene_name = argv[k + 1];
    else if (!std::strcmp(argv[k], "--scene-seed"))
      scene_seed = std::atoll(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--crop"))
      crop = std::max(32, std::atoi(argv[k + 1]));
    else if (!std::strcmp(argv[k], "--stride"))
      depth_options.search_stride = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--ring1"))
      depth_options.max_ring1 = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--type-ranges"))
      depth_options.type_ranges = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--lens-only"))
      lens_only = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--dense"))
      run_dense = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--lens-path"))
      lens_path = argv[k + 1];
    else if (!std::strcmp(argv[k], "--dense-path"))
      dense_path = argv[k + 1];
    else if (!std::strcmp(argv[k], "--seed"))
      seed_mode = argv[k + 1];
    else if (!std::strcmp(argv[k], "--seed-stride"))
      depth_options.seed_search_stride = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-ring1"))
      depth_options.seed_max_ring1 = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-ring2"))
      depth_options.seed_max_ring2 = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-cost-ratio"))
      depth_options.seed_cost_ratio = std::atof(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-flat-stride"))
      depth_options.seed_flat_stride = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-ring2-lines"))
      depth_options.seed_ring2_lines = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-flat-px"))
      depth_options.seed_flat_px = std::atof(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-interp-spread"))
      depth_options.seed_interp_spread = std::atof(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-interp-min"))
      depth_options.seed_interp_min = std::atoi(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--seed-margin"))
      depth_options.seed_margin_px = std::atof(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--frames"))
      frames_file = argv[k + 1];
    else if (!std::strcmp(argv[k], "--tf-only"))
      tf_only_map = argv[k + 1];
    else if (!std::strcmp(argv[k], "--tf-out"))
      tf_out = argv[k + 1];
    else if (!std::strcmp(argv[k], "--tf-baseline"))
      tf_baseline = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--tf-psnr"))
      tf_psnr = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--dense-for-tf"))
      dense_for_tf = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--lens-previous"))
      lens_previous = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--lens-neighbours"))
      lens_options.neighbour_seed = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--lens-grey"))
      lens_options.grey_plane = std::atoi(argv[k + 1]) != 0;
    else if (!std::strcmp(argv[k], "--lens-samples"))
      lens_options.samples = std::atoi(argv[k + 1]);
    else if (SetLensOption(argv[k], argv[k + 1], &lens_options))
      continue;
    else if (!std::strcmp(argv[k], "--ring2"))
      depth_options.max_ring2 = std::atoi(argv[k + 1]);
    else {
      std::fprintf(stderr, "unknown option %s\n", argv[k]);
      return 2;
    }
  }
  if (dense_for_tf && !tf_only_map.empty()) {
    std::fprintf(stderr, "--dense-for-tf 1: not with --tf-only (its MAP holds the whole map)\n");
    return 2;
  }
  if (!run_dense && !lens_only) {
    std::fprintf(stderr, "--dense 0 needs --lens-only 1\n");
    return 2;
  }
  if ((dense_path != "scalar" && dense_path != "simd" && dense_path != "both") ||
      (seed_mode != "full" && seed_mode != "seeded" && seed_mode != "both")) {
    std::fprintf(stderr, "--dense-path: expected scalar, simd or both; --seed: full, seeded or both\n");
    return 2;
  }
  if (lens_path != "scalar" && lens_path != "simd" && lens_path != "both") {
    std::fprintf(stderr, "--lens-path: expected scalar, simd or both\n");
    return 2;
  }
  Expected<synth::SynthParams> params = synth::MakePreset(preset);
  if (!params) {
    std::fprintf(stderr, "%s\n", params.error().message.c_str());
    return 2;
  }
  if (scene_seed < -1) {
    std::fprintf(stderr, "--scene-seed: expected a seed >= 0\n");
    return 2;
  }
  const std::uint64_t scene_rng_seed =
      scene_seed >= 0 ? static_cast<std::uint64_t>(scene_seed) : params->rig.seed;
  Expected<synth::Scene> made = synth::MakeScene(scene_name, scene_rng_seed);
  if (!made) {
    std::fprintf(stderr, "%s\n", made.error().message.c_str());
    return 2;
  }
  const synth::Scene& scene = *made;
  std::printf("bench_depth: preset %s, scene %s (seed %llu), %d threads, %d runs\n",
              preset.c_str(), scene_name.c_str(), static_cast<unsigned long long>(scene_rng_seed),
              tbb::info::default_concurrency(), repeat);
  const synth::PlenopticModel model(params->camera);
  synth::TrajectoryParams tp;
  tp.target_mm = scene.Target();
  tp.distance_mm = params->rig.viewing_distance_mm;
  const Pose world_from_cam = synth::CameraTrajectory(tp).WorldFromCam(0.0);
  double t0 = Now();
  synth::RawFrame raw, white;
  // The files of --frames and --tf-only name what they hold; a scene seed of
  // the command's own is part of the name.
  const std::string frames_key = preset + " " + scene_name +
                                 (scene_seed >= 0 ? " seed " + std::to_string(scene_rng_seed) : "");
  if (!frames_file.empty() && ReadFrames(frames_file, frames_key, &raw, &white)) {
    std::printf("read raw + white %dx%d from %s\n", raw.width, raw.height, frames_file.c_str());
  } else {
    raw = synth::RenderRaw(model, scene, world_from_cam, {});
    synth::RenderOptions white_options;
    white_options.noise_seed = 2;
    white = synth::RenderRaw(model, synth::MakeWhiteScene(), Pose::Identity(), white_options);
    std::printf("rendered raw + white %dx%d in %.1f s (not timed below)\n", raw.width,
                raw.height, Now() - t0);
    if (!frames_file.empty() && !WriteFrames(frames_file, frames_key, raw, white))
      std::fprintf(stderr, "could not write %s\n", frames_file.c_str());
  }
  const MlaCalibration mla = model.ToMlaCalibration();
  const double raw_mp = raw.width * static_cast<double>(raw.height) / 1e6;

  // Grid fit.
  std::vector<double> grid_s;
  GridFitResult fit;
  const bool tf_only = !tf_only_map.empty();
  if (tf_only) run_dense = false;
  for (int r = 0; r < (lens_only || tf_only ? 0 : repeat); ++r) {
    Expected<GridFitResult> g = FitGridToWhiteImage(white.View(), nullptr);
    if (!g) {
      std::fprintf(stderr, "grid fit: %s\n", g.error().message.c_str());
      return 1;
    }
    grid_s.push_back(g->seconds);
    fit = *g;
  }
  if (!lens_only && !tf_only)
    std::printf("grid fit: %.3f s (median), %s\n", Median(grid_s), fit.BriefReport().c_str());

  // Virtual depth.
  CameraIntrinsics k;
  k.main_focal_length_mm = params->camera.main_focal_length_mm;
  k.mla_to_main_lens_mm = params->camera.mla_to_main_lens_mm;
  k.mla_to_sensor_mm = params->camera.mla_to_sensor_mm;
  k.pixel_size_mm = params->camera.pixel_size_mm;
  k.width_px = raw.width;
  k.height_px = raw.height;
  const CameraModel camera(k);
  const MlaGrid grid = MlaGrid::FromCalibration(mla, raw.width, raw.height);
  FrameOptions fo;
  fo.lambda = camera.lambda();
  PlenopticFrame frame;
  VirtualDepthMap depth;  // the default path's map (seeded, SIMD), for the TF image below
  // Run 0 warms up (first touch of the workspace buffers; a pipeline reuses
  // them frame after frame, and first-touch page faults cost ~10 us each on
  // these VMs) and is not timed.
  // Per camera, once (white image, grid): not part of the per-frame time.
  t0 = Now();
  if (!PrepareGeometry(white.View(), raw.width, raw.height, grid, mla, fo, &frame).ok()) {
    std::fprintf(stderr, "prepare geometry failed\n");
    return 1;
  }
  std::printf("per camera, once: devignetting gain and micro-image map %.3f s\n", Now() - t0);
  // The seed: the per-lens depth (SIMD) of the same frame, with its own time.
  std::unique_ptr<LensDepthEstimator> seed_estimator;
  {
    PlenopticFrame geometry;
    if (!PrepareGeometry(white.View(), raw.width, raw.height, grid, mla, fo, &geometry).ok())
      return 1;
    auto made_estimator = LensDepthEstimator::Create(std::move(geometry), mla, lens_options);
    if (!made_estimator) {
      std::fprintf(stderr, "lens depth: %s\n", made_estimator.error().message.c_str());
      return 2;
    }
    seed_estimator = std::move(*made_estimator);
  }
  LensDepthMap seed_map;
  LensSeed seed;
  // Dense paths side by side: (full | seeded) x (scalar | SIMD); per path
  // the per-frame prepare + search (+ per-lens seed) in wall and CPU time,
  // median of the runs, and its accuracy against the ground truth.
  struct DenseResult {
    double wall_s = 0, cpu_s = 0, prepare_s = 0, prepare_cpu_s = 0, seed_s = 0, coverage = 0, median = 1,
           outliers = 1, median_mm = 1;
    DepthStats stats;
  };
  std::vector<std::pair<std::string, DenseResult>> dense_results;
  double depth_mps = 0, depth_wall_s = 0;
  auto run_dense_path = [&](bool seeded, bool simd, VirtualDepthMap* map) -> bool {
    DepthOptions options = depth_options;
    options.simd = simd;
    DenseResult res;
    std::vector<double> wall, cpu, prep, prep_cpu, seed_time;
    for (int r = 0; r <= repeat; ++r) {
      t0 = Now();
      const double cpu0 = ProcessCpuSeconds();
      if (!LoadRaw(raw.View(), &frame).ok()) return false;
      const double t_prepared = Now(), cpu_prepared = ProcessCpuSeconds();
      if (seeded) {
        if (!seed_estimator->Estimate(raw.View(), &seed_map).ok()) return false;
        if (!SeedFromLensDepth(frame, seed_map, &seed).ok()) return false;
        if (dense_for_tf) LensesHeldForTf(frame, seed, &seed.skip);
      }
      const double t_seeded = Now();
      if (!EstimateVirtualDepth(frame, mla, options, seeded ? &seed : nullptr, map).ok())
        return false;
      if (r > 0) {
        wall.push_back(Now() - t0);
        cpu.push_back(ProcessCpuSeconds() - cpu0);
        prep.push_back(t_prepared - t0);
        prep_cpu.push_back(cpu_prepared - cpu0);
        seed_time.push_back(t_seeded - t_prepared);
      }
    }
    res.wall_s = Median(wall);
    res.cpu_s = Median(cpu);
    res.prepare_s = Median(prep);
    res.prepare_cpu_s = Median(prep_cpu);
    res.seed_s = Median(seed_time);
    res.stats = map->stats;
    long long textured = 0, covered = 0, outliers = 0;
    std::vector<double> rel, rel_mm;
    for (std::size_t i = 0; i < map->virtual_depth.size(); ++i) {
      const float truth = raw.virtual_depth[i];
      if (!map->textured[i] || std::isnan(truth)) continue;
      ++textured;
      const float v = map->virtual_depth[i];
      if (std::isnan(v)) continue;
      ++covered;
      rel.push_back(std::abs(1.0 / v - 1.0 / truth) * truth);
      const double z_true = camera.DepthOfVirtualDepth(truth);
      rel_mm.push_back(std::abs(camera.DepthOfVirtualDepth(v) - z_true) / z_true);
      if (std::abs(v - truth) / truth > 0.10) ++outliers;
    }
    res.coverage = textured ? static_cast<double>(covered) / textured : 0;
    res.median = rel.empty() ? 1 : Median(rel);
    res.outliers = covered ? static_cast<double>(outliers) / covered : 1;
    res.median_mm = rel_mm.empty() ? 1 : Median(rel_mm);
    const std::string name = std::string(seeded ? "seeded" : "full") + " " + (simd ? "simd" : "scalar");
    dense_results.emplace_back(name, res);
    const bool gates = res.coverage >= 0.5 && res.median <= 0.02 && res.outliers <= 0.05;
    std::printf(
        "depth %s: %.2f raw MP/s (%.3f s median per %.1f MP frame: prepare %.3f (CPU %.3f), "
        "per-lens seed %.3f, search %.3f; CPU %.3f s, all threads); coverage %.1f %% of textured, median "
        "|dz|/z %.2f %%, outliers %.2f %%, metric median |dZ|/Z %.2f %%: gates %s (%s)\n",
        name.c_str(), raw_mp / res.wall_s, res.wall_s, raw_mp, res.prepare_s, res.prepare_cpu_s, res.seed_s,
        res.wall_s - res.prepare_s - res.seed_s, res.cpu_s, 100 * res.coverage, 100 * res.median,
        100 * res.outliers, 100 * res.median_mm, gates ? "hold" : "DO NOT hold",
        LoadAverage().c_str());
    std::printf("depth %s: %s\n", name.c_str(), res.stats.BriefReport().c_str());
    return true;
  };
  if (run_dense) {
    for (const bool seeded : {false, true})
      for (const bool simd : {false, true}) {
        if ((seeded && seed_mode == "full") || (!seeded && seed_mode == "seeded")) continue;
        if ((simd && dense_path == "scalar") || (!simd && dense_path == "simd")) continue;
        // The last path run (seeded SIMD by default) is the map the TF image uses.
        if (!run_dense_path(seeded, simd, &depth)) {
          std::fprintf(stderr, "depth failed\n");
          return 1;
        }
      }
    depth_wall_s = dense_results.back().second.wall_s;
    depth_mps = raw_mp / depth_wall_s;
    // The side-by-side table and the gate (>= 65 raw MP/s; accuracy of the
    // seeded path within 1 % absolute of the full search's).
    const DenseResult* full = nullptr;
    for (const auto& [name, res] : dense_results)
      if (name.rfind("full", 0) == 0) full = &res;
    std::printf("depth paths (%s):\n", LoadAverage().c_str());
    std::printf("  %-14s %9s %9s %9s %9s %9s %9s\n", "path", "raw MP/s", "wall s", "CPU s",
                "coverage", "median", "outliers");
    for (const auto& [name, res] : dense_results) {
      std::printf("  %-14s %9.2f %9.3f %9.3f %8.2f%% %8.2f%% %8.2f%%", name.c_str(),
                  raw_mp / res.wall_s, res.wall_s, res.cpu_s, 100 * res.coverage,
                  100 * res.median, 100 * res.outliers);
      if (full != nullptr && name.rfind("seeded", 0) == 0) {
        const bool within = res.coverage >= full->coverage - 0.01 &&
                            res.median <= full->median + 0.01 &&
                            res.outliers <= full->outliers + 0.01;
        std::printf("  speed x%.1f of full, accuracy %s", full->wall_s / res.wall_s,
                    within ? "within 1 % of full" : "NOT within 1 % of full");
      }
      std::printf("\n");
    }
    std::printf("depth gate (>= 65 raw MP/s, %s): %s\n", dense_results.back().first.c_str(),
                depth_mps >= 65 ? "holds" : "DOES NOT hold");
  }

  // Per-lens virtual depth on the same frame, the scalar and the SIMD
  // strip search (LensDepthOptions::simd) side by side; the dense search
  // above is its baseline.
  std::optional<synth::TfGroundTruth> tf_truth;  // for the previews' PSNR
  if (tf_only && !ReadDenseMap(tf_only_map, frames_key, &depth)) {
    // The map the TF image reads: the default path's (seeded, SIMD), once.
    DepthOptions options = depth_options;
    options.simd = true;
    if (!LoadRaw(raw.View(), &frame).ok() ||
        !seed_estimator->Estimate(raw.View(), &seed_map).ok() ||
        !SeedFromLensDepth(frame, seed_map, &seed).ok() ||
        !EstimateVirtualDepth(frame, mla, options, &seed, &depth).ok()) {
      std::fprintf(stderr, "depth failed\n");
      return 1;
    }
    if (!WriteDenseMap(tf_only_map, frames_key, depth))
      std::fprintf(stderr, "could not write %s\n", tf_only_map.c_str());
  }
  for (const bool simd : {false, true}) {
    if (tf_only) break;
    if ((simd && lens_path == "scalar") || (!simd && lens_path == "simd")) continue;
    const char* path = simd ? "simd" : "scalar";
    LensDepthOptions options = lens_options;
    options.simd = simd;
    PlenopticFrame geometry;
    if (!PrepareGeometry(white.View(), raw.width, raw.height, grid, mla, fo, &geometry).ok())
      return 1;
    auto estimator = LensDepthEstimator::Create(std::move(geometry), mla, options);
    if (!estimator) {
      std::fprintf(stderr, "lens depth: %s\n", estimator.error().message.c_str());
      return 2;
    }
    // --lens-previous 1: each run seeded by the run before's map (the
    // temporal seed of a camera that did not move: its best case).
    std::array<LensDepthMap, 2> maps;
    TfImage preview;
    std::vector<double> lens_s, lens_cpu_s, preview_s, preview_cpu_s;
    CALLGRIND_START_INSTRUMENTATION;
    for (int r = 0; r <= repeat; ++r) {  // run 0: warm-up (first touch), not timed
      LensDepthMap& lens = maps[r % 2];
      const LensDepthMap* previous = lens_previous && r > 0 ? &maps[(r + 1) % 2] : nullptr;
      t0 = Now();
      const double cpu0 = ProcessCpuSeconds();
      if (!(*estimator)->Estimate(raw.View(), &lens, previous).ok()) return 1;
      const double t1 = Now();
      const double cpu1 = ProcessCpuSeconds();
      if (r > 0) lens_cpu_s.push_back(cpu1 - cpu0);
      if (!(*estimator)->RenderPreview(raw.View(), 512, &lens, &preview).ok()) return 1;
      if (r > 0) {
        lens_s.push_back(t1 - t0);
        preview_s.push_back(Now() - t1);
        preview_cpu_s.push_back(ProcessCpuSeconds() - cpu1);
      }
    }
    CALLGRIND_STOP_INSTRUMENTATION;
    const LensDepthMap& lens = maps[repeat % 2];
    std::vector<float> truth, dense;
    LensMedianOf((*estimator)->geometry(), lens.grid, raw.virtual_depth, 0.5, &truth);
    if (run_dense)
      LensMedianOf((*estimator)->geometry(), lens.grid, depth.virtual_depth, 0.1, &dense);
    auto measure = [&](const std::vector<float>& v, long long* tex, long long* est,
                       long long* out_n) {
      std::vector<double> rel;
      *tex = *est = *out_n = 0;
      for (std::size_t c = 0; c < truth.size(); ++c) {
        if (!lens.textured[c] || !std::isfinite(truth[c])) continue;
        ++*tex;
        if (!std::isfinite(v[c])) continue;
        ++*est;
        rel.push_back(std::abs(v[c] - truth[c]) / truth[c]);
        if (rel.back() > 0.10) ++*out_n;
      }
      return rel.empty() ? 1.0 : Median(rel);
    };
    long long tex = 0, est = 0, outl = 0;
    const double lens_median = measure(lens.virtual_depth, &tex, &est, &outl);
    const double lens_ms = 1e3 * Median(lens_s);
    const double lens_cov = tex ? static_cast<double>(est) / tex : 0;
    std::printf("lens depth %s: %s\n", path, lens.stats.BriefReport().c_str());
    std::printf(
        "lens depth %s: %.1f ms median per %.1f MP frame (%zu lenses, %.0f frames/s; CPU %.1f ms "
        "per frame, all threads)",
        path, lens_ms, raw_mp, (*estimator)->geometry().lenses.size(), 1e3 / lens_ms,
        1e3 * Median(lens_cpu_s));
    if (run_dense)
      std::printf("; dense search on the same frame %.0f ms: ratio %.0fx", 1e3 * depth_wall_s,
                  1e3 * depth_wall_s / lens_ms);
    std::printf(" (%s)\n", LoadAverage().c_str());
    std::printf(
        "lens depth %s vs truth (per-lens median): %lld of %lld textured lenses (%.1f %%), median "
        "|dv|/v %.2f %%, outliers (> 10 %%) %.2f %%: gates (<= 50 ms, >= 90 %%, <= 2 %%) %s\n",
        path, est, tex, 100 * lens_cov, 100 * lens_median, est ? 100.0 * outl / est : 0.0,
        lens_ms <= 50 && lens_cov >= 0.9 && lens_median <= 0.02 ? "hold" : "DO NOT hold");
    if (run_dense && !simd) {
      long long dtex = 0, dest = 0, doutl = 0;
      const double dense_median = measure(dense, &dtex, &dest, &doutl);
      std::printf(
          "dense map reduced per lens, same lenses: %lld of %lld (%.1f %%), median |dv|/v %.2f "
          "%%, outliers %.2f %%\n",
          dest, dtex, dtex ? 100.0 * dest / dtex : 0.0, 100 * dense_median,
          dest ? 100.0 * doutl / dest : 0.0);
    }
    // Against the all-in-focus ground truth at the preview's TF positions
    // ((a + 1/2) s - 1/2, rounded) where it sees a surface (rendered once,
    // not timed): RMS over the channels and PSNR = 20 log10(255 / RMS).
    if (!tf_truth) tf_truth = synth::RenderTfGroundTruth(model, scene, world_from_cam);
    double sum2 = 0;
    long long n2 = 0;
    const int channels = preview.format == PixelFormat::kBgr8 ? 3 : 1;
    const double step = static_cast<double>(std::max(tf_truth->width, tf_truth->height)) /
                        std::max(preview.width, preview.height);
    for (int b = 0; b < preview.height; ++b)
      for (int a = 0; a < preview.width; ++a) {
        const int u = static_cast<int>(std::lround((a + 0.5) * step - 0.5));
        const int w = static_cast<int>(std::lround((b + 0.5) * step - 0.5));
        if (u >= tf_truth->width || w >= tf_truth->height) continue;
        const std::size_t t = static_cast<std::size_t>(w) * tf_truth->width + u;
        if (!std::isfinite(tf_truth->depth_mm[t])) continue;
        const std::uint8_t* pix =
            preview.pixels.data() + (static_cast<std::size_t>(b) * preview.width + a) * channels;
        for (int ch = 0; ch < channels; ++ch) {
          // A Mono8 preview against the truth's grey (the channel mean).
          const double truth = channels == 3 ? tf_truth->bgr[t * 3 + ch]
                                             : (tf_truth->bgr[t * 3] + tf_truth->bgr[t * 3 + 1] +
                                                tf_truth->bgr[t * 3 + 2]) / 3.0;
          const double d = pix[ch] - truth;
          sum2 += d * d;
          ++n2;
        }
      }
    const double rms = n2 > 0 ? std::sqrt(sum2 / n2) : 0.0;
    std::printf(
        "lens preview %s: %dx%d in %.1f ms median (CPU %.1f ms, all threads); against the "
        "all-in-focus truth: RMS %.2f DN, PSNR %.2f dB (%lld samples)\n",
        path, preview.width, preview.height, 1e3 * Median(preview_s), 1e3 * Median(preview_cpu_s),
        rms, rms > 0 ? 20 * std::log10(255 / rms) : 0.0, n2);
  }
  if (lens_only) return 0;

  if (!tf_only) {
    // Naive reference on a crop at the image centre (one run; it is slow).
    const int cx = raw.width / 2 - crop / 2, cy = raw.height / 2 - crop / 2;
    std::vector<float> naive;
    t0 = Now();
    const long long naive_pixels = NaiveBlockMatching(frame, mla, cx, cy, crop, &naive);
    const double naive_s = Now() - t0;
    const double naive_mps = crop * static_cast<double>(crop) / 1e6 / naive_s;
    std::printf(
        "naive block matching: %.4f raw MP/s (%dx%d crop, %lld pixels, %.2f s, 1 thread); "
        "ratio %.1fx\n",
        naive_mps, crop, crop, naive_pixels, naive_s, depth_mps / naive_mps);
  } else if (!LoadRaw(raw.View(), &frame).ok()) {
    return 1;
  }

  // TF image, two ways on the same dense map, alternating run by run: the
  // TF depth from the frame's per-lens depth where it holds and the dense
  // map's pixels elsewhere (the chain's way; the gate), and from every
  // dense pixel (the baseline). The per-lens depth is the frame's (the
  // dense search's seed), estimated once here, not timed.
  if (!seed_estimator->Estimate(raw.View(), &seed_map).ok()) {
    std::fprintf(stderr, "lens depth failed\n");
    return 1;
  }
  std::printf("tf: the frame's %s\n", seed_map.stats.BriefReport().c_str());
  struct TfRun {
    TfDepthMap depth;
    TfImage image;
    std::vector<double> wall_s, cpu_s, depth_s, depth_cpu_s;
  };
  std::array<TfRun, 2> tf_runs;  // [0] per-lens + dense at edges, [1] every dense pixel
  const int tf_ways = tf_baseline ? 2 : 1;
  for (int r = 0; r <= repeat; ++r) {  // run 0: warm-up, not timed
    for (int way = 0; way < tf_ways; ++way) {
      TfRun& run = tf_runs[way];
      t0 = Now();
      const double cpu0 = ProcessCpuSeconds();
      const Status made = way == 0 ? VirtualDepthToTf(frame, depth, seed_map, TfOptions{}, &run.depth)
                                   : VirtualDepthToTf(frame, depth, TfOptions{}, &run.depth);
      if (!made.ok()) {
        std::fprintf(stderr, "TF depth: %s\n", made.error().message.c_str());
        return 1;
      }
      if (r > 0) {
        run.depth_s.push_back(Now() - t0);
        run.depth_cpu_s.push_back(ProcessCpuSeconds() - cpu0);
      }
      if (!RenderTotalFocus(frame, mla, run.depth, TfOptions{}, &run.image).ok()) {
        std::fprintf(stderr, "TF failed\n");
        return 1;
      }
      if (r > 0) {
        run.wall_s.push_back(Now() - t0);
        run.cpu_s.push_back(ProcessCpuSeconds() - cpu0);
      }
    }
  }
  TfDepthMap& tf_depth = tf_runs[0].depth;
  TfImage& tf = tf_runs[0].image;
  // One thread, each way `repeat` times alternately: CPU seconds without
  // the idle workers' spinning that an all-threads run counts on a loaded
  // machine (the figure to compare there), TF depth map and whole.
  std::vector<double> tf_one_s;
  std::array<std::vector<double>, 2> one_cpu_s, one_depth_cpu_s;
  tbb::task_arena one(1);
  one.execute([&] {
    for (int r = 0; r < repeat; ++r)
      for (int way = 0; way < tf_ways; ++way) {
        TfRun& run = tf_runs[way];
        t0 = Now();
        const double cpu0 = ProcessCpuSeconds();
        (void)(way == 0 ? VirtualDepthToTf(frame, depth, seed_map, TfOptions{}, &run.depth)
                        : VirtualDepthToTf(frame, depth, TfOptions{}, &run.depth));
        one_depth_cpu_s[way].push_back(ProcessCpuSeconds() - cpu0);
        (void)RenderTotalFocus(frame, mla, run.depth, TfOptions{}, &run.image);
        one_cpu_s[way].push_back(ProcessCpuSeconds() - cpu0);
        if (way == 0) tf_one_s.push_back(Now() - t0);
      }
  });
  std::printf(
      "tf, one thread (median of %d): CPU %.3f s (TF depth map %.3f s) against the baseline's "
      "%.3f s (%.3f s): ratio %.2fx (TF depth map %.2fx)\n",
      repeat, Median(one_cpu_s[0]), Median(one_depth_cpu_s[0]), Median(one_cpu_s[1]),
      Median(one_depth_cpu_s[1]), Median(one_cpu_s[1]) / Median(one_cpu_s[0]),
      Median(one_depth_cpu_s[1]) / Median(one_depth_cpu_s[0]));
  // Against the all-in-focus ground truth over the TF pixels that see a
  // surface (not timed): PSNR = 20 log10(255 / RMS), RMS over the channels;
  // and the per-lens way's image against the baseline's.
  if (!tf_truth && tf_psnr) tf_truth = synth::RenderTfGroundTruth(model, scene, world_from_cam);
  auto psnr = [&](const TfImage& image, const std::uint8_t* reference) {
    if (reference == nullptr && !tf_truth) return std::nan("");
    double sum2 = 0;
    long long n = 0;
    const int channels = image.format == PixelFormat::kBgr8 ? 3 : 1;
    for (std::size_t t = 0; t < static_cast<std::size_t>(image.width) * image.height; ++t) {
      if (reference == nullptr && (static_cast<int>(t % image.width) >= tf_truth->width ||
                                   static_cast<int>(t / image.width) >= tf_truth->height))
        continue;
      const std::size_t g = reference == nullptr ? (t / image.width) * tf_truth->width +
                                                       t % image.width
                                                 : t;
      if (reference == nullptr && !std::isfinite(tf_truth->depth_mm[g])) continue;
      for (int ch = 0; ch < channels; ++ch) {
        double truth;
        if (reference != nullptr)
          truth = reference[t * channels + ch];
        else if (channels == 3)
          truth = tf_truth->bgr[g * 3 + ch];
        else
          truth = (tf_truth->bgr[g * 3] + tf_truth->bgr[g * 3 + 1] + tf_truth->bgr[g * 3 + 2]) / 3.0;
        const double d = image.pixels[t * channels + ch] - truth;
        sum2 += d * d;
        ++n;
      }
    }
    const double rms = n > 0 ? std::sqrt(sum2 / n) : 0.0;
    return rms > 0 ? 20 * std::log10(255 / rms) : 99.0;
  };
  const double tf_mp = tf.width * static_cast<double>(tf.height) / 1e6;
  const char* way_name[2] = {"per-lens depth + dense at edges", "every dense pixel (baseline)"};
  for (int way = 0; way < tf_ways; ++way) {
    const TfRun& run = tf_runs[way];
    std::printf(
        "tf (%s): %.2f output MP/s (%.3f s median per %.2f MP; CPU %.3f s, all threads; TF depth "
        "map %.3f s, CPU %.3f s of it); PSNR against the all-in-focus truth %.2f dB\n",
        way_name[way], tf_mp / Median(run.wall_s), Median(run.wall_s), tf_mp, Median(run.cpu_s),
        Median(run.depth_s), Median(run.depth_cpu_s), psnr(run.image, nullptr));
  }
  std::printf("tf: %lld of %lld micro images from their lens depth; image against the baseline's: "
              "PSNR %.2f dB\n",
              tf_depth.lenses_held, tf_depth.lenses,
              tf_baseline ? psnr(tf, tf_runs[1].image.pixels.data()) : std::nan(""));
  // The TF depth map (what the live chain publishes, as block means) against
  // the truth's depth on the TF grid, not timed: of the TF pixels that see a
  // surface, the share with a depth, median |dZ|/Z and the share beyond 10 %.
  for (int way = 0; way < tf_ways && tf_truth; ++way) {
    const TfDepthMap& map = tf_runs[way].depth;
    long long seen = 0, covered = 0, outliers = 0;
    std::vector<double> rel;
    for (int y = 0; y < std::min(map.height, tf_truth->height); ++y)
      for (int x = 0; x < std::min(map.width, tf_truth->width); ++x) {
        const float z_true = tf_truth->depth_mm[static_cast<std::size_t>(y) * tf_truth->width + x];
        if (!std::isfinite(z_true)) continue;
        ++seen;
        const float v = map.virtual_depth[static_cast<std::size_t>(y) * map.width + x];
        if (!std::isfinite(v)) continue;
        ++covered;
        rel.push_back(std::abs(camera.DepthOfVirtualDepth(v) - z_true) / z_true);
        outliers += rel.back() > 0.10;
      }
    std::printf("tf depth map (%s) against the truth: %.2f %% of %lld TF pixels that see a "
                "surface, median |dZ|/Z %.3f %%, outliers (> 10 %%) %.3f %%\n",
                way_name[way], seen ? 100.0 * covered / seen : 0.0, seen,
                rel.empty() ? 100.0 : 100 * Median(rel),
                covered ? 100.0 * outliers / covered : 100.0);
  }
  const std::vector<double>& tf_s = tf_runs[0].wall_s;
  std::printf(
      "tf: %.2f output MP/s (%.3f s median per %.2f MP; CPU %.3f s, all threads); baseline %.2f "
      "MP/s (CPU %.3f s): ratio %.2fx (CPU %.2fx); one thread %.2f MP/s; gate (>= 100 output "
      "MP/s) %s (%s)\n",
      tf_mp / Median(tf_s), Median(tf_s), tf_mp, Median(tf_runs[0].cpu_s),
      tf_mp / Median(tf_runs[1].wall_s), Median(tf_runs[1].cpu_s),
      Median(tf_runs[1].wall_s) / Median(tf_s), Median(tf_runs[1].cpu_s) / Median(tf_runs[0].cpu_s),
      tf_mp / Median(tf_one_s), tf_mp / Median(tf_s) >= 100 ? "holds" : "DOES NOT hold",
      LoadAverage().c_str());
  if (!tf_out.empty()) {
    // PGM / PPM (P6 wants RGB: BGR swapped).
    std::FILE* file = std::fopen(tf_out.c_str(), "wb");
    const int channels = tf.format == PixelFormat::kBgr8 ? 3 : 1;
    bool ok = file != nullptr;
    if (ok) {
      std::fprintf(file, "P%d\n%d %d\n255\n", channels == 3 ? 6 : 5, tf.width, tf.height);
      std::vector<std::uint8_t> out = tf.pixels;
      if (channels == 3)
        for (std::size_t i = 0; i + 2 < out.size(); i += 3) std::swap(out[i], out[i + 2]);
      ok = std::fwrite(out.data(), 1, out.size(), file) == out.size();
      ok = std::fclose(file) == 0 && ok;
    }
    if (!ok) std::fprintf(stderr, "could not write %s\n", tf_out.c_str());
  }
  // Naive reference on a central crop of the TF grid (one thread).
  const int tf_crop = std::min({crop, tf.width, tf.height});
  std::vector<float> naive_tf;
  t0 = Now();
  const long long naive_tf_pixels = NaiveTotalFocus(
      frame, tf_depth, tf.width / 2 - tf_crop / 2, tf.height / 2 - tf_crop / 2, tf_crop, &naive_tf);
  const double naive_tf_s = Now() - t0;
  const double naive_tf_mps = naive_tf_pixels / 1e6 / naive_tf_s;
  std::printf(
      "naive TF (every micro image that sees the point, averaged): %.3f output MP/s (%dx%d crop, "
      "%.2f s, 1 thread); ratio %.1fx\n",
      naive_tf_mps, tf_crop, tf_crop, naive_tf_s, tf_mp / Median(tf_s) / naive_tf_mps);
  return 0;
}
