// bench_map_matching: one frame of camera X matched against camera 0's
// reference map and registered by PnP (registration/map/frame_registration.h,
// as `lifmcr register --method pnp` runs it), for maps of growing size, with
// the map's approximate index (kd-forest, MapMatching() in
// registration/features/features.h) and with the exact brute-force matcher,
// the baseline, in the same run.
//
// The maps are real: one map from the ground truth of camera 0's frames of a
// synthetic `small` rig (registration/map/ground_truth_map.h: SIFT on the
// ground-truth TF image, points back-projected with the true depth and
// placed by the true pose; a keypoint that matches an existing point within
// 5 mm joins its track), built once from every frame, and the smaller maps
// its first N points (the points of its first frames; a map smaller than
// asked is used whole, the row says so: 190 triggers give about 73 000
// points, about 385 new ones a trigger). Building it matches
// each frame against the map so far with the approximate matcher (exact, a
// 100 000-point map takes minutes to build); the maps' content is the same
// for both matchers compared here. The query frames are camera X's first
// frames (those the first map frames saw), from the raw frames through
// processing (--observations raw, as `register` runs) or from the ground
// truth.
//
// Per map size and matcher: the index build (once per map, not per frame),
// then per frame (median over the query frames, each the fastest of
// --repeat runs) the wall time of matching and of matching + PnP, and the
// process CPU time per frame (both cores count: the approximate search
// runs its queries in parallel); the matches, the share of the exact
// matcher's matches the approximate one found (recall) and the share of its
// own that the exact one also made (precision); PnP inliers and the error
// of w0_from_cam against the ground truth. The ratio is exact / approximate
// of matching + PnP (wall).
//
// The sequence is written first by `lifmcr synth --preset small --cameras 2`
// (not timed) unless --sequence gives one.
//   bench_map_matching [--sequence SEQ_DIR] [--frames 190] [--map-points 1700,20000,100000]
//                      [--queries 3] [--observations raw|ground-truth] [--max-features 4000]
//                      [--repeat 3] [--keep] [--map-cache DIR] [--checks 64[,128...]]
//                      [--kd-trees 4] [--threads N]
// --map-cache keeps the built map in DIR (reference-map files) and reads it
// from there next time; --checks and --kd-trees replace MapMatching()'s
// search (one approximate row per checks value, the last one in the
// summary); --threads limits TBB's and OpenCV's pools (1: the CPU time is
// the work alone, without idle workers' spinning).

#include "bench/bench_usage.h"
#include "evaluation/evaluation_inputs.h"
#include "processing/camera_model.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/features/features.h"
#include "registration/features/frame_observations.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/map/frame_registration.h"
#include "registration/map/ground_truth_map.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"

#include <opencv2/core/utility.hpp>
#include <tbb/global_control.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace lifmcr;
using namespace lifmcr::registration;
namespace fs = std::filesystem;

namespace {

constexpr char kUsage[] =
    "usage: bench_map_matching [--sequence SEQ_DIR] [--frames 190] [--map-points 1700,20000,100000]\n"
    "                          [--queries 3] [--observations raw|ground-truth] [--max-features 4000]\n"
    "                          [--repeat 3] [--keep] [--map-cache DIR] [--checks 64[,128...]]\n"
    "                          [--kd-trees 4] [--threads N]\n"
    "One frame of camera X matched against camera 0's reference map (a ground-truth map of a\n"
    "synthetic small rig, cut to each --map-points size) and registered by PnP, with the map's\n"
    "approximate index and with the exact matcher (the baseline) in the same run: ms per frame,\n"
    "the ratio exact / approximate, match recall and precision against the exact matcher, PnP\n"
    "inliers and the pose error against the ground truth. Without --sequence a rig of --frames\n"
    "triggers is written first by `lifmcr synth` (not timed; --keep leaves it in place).\n"
    "--map-cache DIR keeps the built map there and reads it next time; --checks (a list) and\n"
    "--kd-trees replace the default search (one row per checks value); --threads limits the\n"
    "thread pools (1: CPU time without idle workers' spinning).\n";

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double CpuNow() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::vector<int> ParseInts(const std::string& list) {
  std::vector<int> out;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ',')) out.push_back(std::atoi(item.c_str()));
  return out;
}

std::string LoadAverage() {
  double l[3] = {0, 0, 0};
  if (getloadavg(l, 3) != 3) return "unknown";
  char text[64];
  std::snprintf(text, sizeof text, "%.2f %.2f %.2f", l[0], l[1], l[2]);
  return text;
}

struct Row {
  double match_ms = 0, total_ms = 0, cpu_ms = 0;
  double matches = 0, recall = 0, precision = 0, inliers = 0, t_mm = 0, r_deg = 0;
  int registered = 0;
};

struct Query {
  FrameObservations obs;
  Pose world_from_cam;
};

// Matching + PnP of every query frame against `index` with `options`:
// medians over the frames; recall and precision against `exact` (one match
// set per frame).
Row Measure(const MapIndex& index, const processing::CameraModel& camera,
            const std::vector<Query>& queries, const FrameRegistrationOptions& options,
            const std::vector<std::set<std::pair<int, int>>>& exact, int repeat) {
  std::vector<double> match_ms, total_ms, matches, recall, precision, inliers, t_mm, r_deg;
  Row row;
  double cpu = 0;
  for (std::size_t q = 0; q < queries.size(); ++q) {
    const FrameObservations& obs = queries[q].obs;
    FrameRegistration best;
    double best_seconds = 1e30, best_match = 1e30;
    for (int r = 0; r < repeat; ++r) {
      const double c0 = CpuNow();
      FrameRegistration result = RegisterFrame(index, camera, obs, RegistrationMethod::kPnp, options);
      cpu += CpuNow() - c0;
      best_match = std::min(best_match, result.match_seconds);
      if (result.seconds < best_seconds) {
        best_seconds = result.seconds;
        best = std::move(result);
      }
    }
    match_ms.push_back(1e3 * best_match);
    total_ms.push_back(1e3 * best_seconds);
    const std::vector<Match> m = MatchDescriptors(obs.features.descriptors.data(),
                                                  obs.features.size(), *index.descriptors,
                                                  options.match);
    std::size_t common = 0;
    for (const Match& x : m) common += exact[q].count({x.query, x.train});
    matches.push_back(static_cast<double>(m.size()));
    recall.push_back(exact[q].empty() ? 1.0 : static_cast<double>(common) / exact[q].size());
    precision.push_back(m.empty() ? 1.0 : static_cast<double>(common) / m.size());
    inliers.push_back(static_cast<double>(best.inliers));
    if (best.success) {
      ++row.registered;
      t_mm.push_back(TranslationDifference(best.w0_from_cam.pose, queries[q].world_from_cam));
      r_deg.push_back(RotationDifferenceDeg(best.w0_from_cam.pose, queries[q].world_from_cam));
    }
  }
  row.match_ms = Median(match_ms);
  row.total_ms = Median(total_ms);
  row.cpu_ms = 1e3 * cpu / static_cast<double>(queries.size() * static_cast<std::size_t>(repeat));
  row.matches = Median(matches);
  row.recall = Median(recall);
  row.precision = Median(precision);
  row.inliers = Median(inliers);
  row.t_mm = Median(t_mm);
  row.r_deg = Median(r_deg);
  return row;
}

void PrintRow(const char* matcher, const Row& r, int frames) {
  std::printf("  %-12s match %8.2f ms  match+pnp %8.2f ms  cpu %8.2f ms  matches %6.0f  "
              "recall %.3f  precision %.3f  inliers %6.0f  error %.3f mm / %.4f deg  "
              "registered %d/%d\n",
              matcher, r.match_ms, r.total_ms, r.cpu_ms, r.matches, r.recall, r.precision,
              r.inliers, r.t_mm, r.r_deg, r.registered, frames);
}

}  // namespace

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // lines as they come, also into a file
  std::string sequence, observations = "raw";
  std::vector<int> sizes = {1700, 20000, 100000};
  std::vector<int> checks = {MapMatching().kd_tree_checks};
  std::string map_cache;
  int frames = 190, queries_wanted = 3, max_features = 4000, repeat = 3, threads = 0;
  int kd_trees = MapMatching().kd_trees;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--sequence") sequence = next();
    else if (a == "--frames") frames = std::atoi(next().c_str());
    else if (a == "--map-points") sizes = ParseInts(next());
    else if (a == "--queries") queries_wanted = std::atoi(next().c_str());
    else if (a == "--observations") observations = next();
    else if (a == "--max-features") max_features = std::atoi(next().c_str());
    else if (a == "--repeat") repeat = std::atoi(next().c_str());
    else if (a == "--keep") keep = true;
    else if (a == "--map-cache") map_cache = next();
    else if (a == "--checks") checks = ParseInts(next());
    else if (a == "--kd-trees") kd_trees = std::atoi(next().c_str());
    else if (a == "--threads") threads = std::atoi(next().c_str());
    else return std::fputs(kUsage, stderr), 2;
  }
  if (frames < 1 || queries_wanted < 1 || repeat < 1 || sizes.empty() || checks.empty() ||
      kd_trees < 1 || threads < 0 ||
      (observations != "raw" && observations != "ground-truth"))
    return std::fputs(kUsage, stderr), 2;
  std::printf("load average before: %s\n", LoadAverage().c_str());
  // --threads: TBB's (the approximate search) and OpenCV's (brute force) pools.
  std::optional<tbb::global_control> limit;
  if (threads > 0) {
    limit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    cv::setNumThreads(threads);
  }

  fs::path tmp;
  if (sequence.empty()) {
    tmp = fs::temp_directory_path() / ("bench_map_matching_" + std::to_string(::getpid()));
    fs::create_directories(tmp);
    const std::string command = std::string(LIFMCR_BINARY) + " synth --out " + tmp.string() +
                                " --preset small --cameras 2 --frames " + std::to_string(frames) +
                                " --quiet";
    std::printf("writing the sequence (not timed): %s\n", command.c_str());
    std::fflush(stdout);
    if (std::system(command.c_str()) != 0) return 1;
    sequence = (tmp / "00_Synthetic" / "Sequence_00").string();
  }
  const fs::path seq = sequence;
  const fs::path cameras_yaml = layout::CamerasYamlPath(seq);
  Expected<SynthGroundTruthInfo> info = ReadCamerasYaml(cameras_yaml);
  if (!info) return std::fprintf(stderr, "%s\n", info.error().message.c_str()), 1;
  if (info->serials.size() < 2)
    return std::fprintf(stderr, "%s: needs two cameras\n", cameras_yaml.c_str()), 1;
  const std::string zero = info->serials[0], x = info->serials[1];
  Expected<CameraCalibration> k0 = ReadCameraCalibration(cameras_yaml, zero);
  Expected<CameraCalibration> kx = ReadCameraCalibration(cameras_yaml, x);
  if (!k0 || !kx) return std::fprintf(stderr, "%s: no calibration\n", cameras_yaml.c_str()), 1;
  const processing::CameraModel camera0(k0->intrinsics), camera_x(kx->intrinsics);
  Expected<std::vector<FramePose>> poses0 = ReadPosesCsv(layout::PosesCsvPath(seq, zero));
  Expected<std::vector<FramePose>> poses_x = ReadPosesCsv(layout::PosesCsvPath(seq, x));
  if (!poses0 || !poses_x) return std::fprintf(stderr, "no ground-truth poses\n"), 1;

  FeatureOptions features;
  features.max_features = max_features;
  // The map: every frame of camera 0 that has a ground-truth image.
  Expected<std::unique_ptr<FrameObserver>> map_observer = FrameObserver::Open(
      ObservationSource::kGroundTruth, seq, zero, camera0, {}, features);
  if (!map_observer) return std::fprintf(stderr, "%s\n", map_observer.error().message.c_str()), 1;
  const std::vector<std::int64_t> map_frames = (*map_observer)->frames();
  GroundTruthMapOptions map_options;
  map_options.features = features;
  map_options.match = MapMatching();
  double t = Now();
  Expected<ReferenceMap> full = Error{""};
  const bool cached = !map_cache.empty() && fs::exists(fs::path(map_cache) / "descriptors.bin");
  if (cached)
    full = ReadReferenceMap(map_cache);
  else
    full = BuildGroundTruthMap(seq, zero, map_frames, camera0, map_options);
  if (!full) return std::fprintf(stderr, "%s\n", full.error().message.c_str()), 1;
  if (!map_cache.empty() && !cached)
    if (Status st = WriteReferenceMap(map_cache, *full); !st)
      return std::fprintf(stderr, "%s\n", st.error().message.c_str()), 1;
  std::printf("map: camera %s, %zu frames, %zu points (%s in %.1f s, not timed)\n", zero.c_str(),
              full->images.size(), full->points.size(), cached ? "read" : "built",
              Now() - t);

  // The query frames of camera X.
  Expected<std::unique_ptr<FrameObserver>> observer = FrameObserver::Open(
      observations == "raw" ? ObservationSource::kRaw : ObservationSource::kGroundTruth, seq, x,
      camera_x, cameras_yaml, features);
  if (!observer) return std::fprintf(stderr, "%s\n", observer.error().message.c_str()), 1;
  std::map<std::int64_t, Pose> truth_x;
  for (const FramePose& p : *poses_x) truth_x[p.frame] = p.world_from_cam;
  std::vector<Query> queries;
  for (const std::int64_t f : (*observer)->frames()) {
    if (static_cast<int>(queries.size()) >= queries_wanted) break;
    Expected<FrameObservations> obs = (*observer)->Observe(f);
    if (!obs) return std::fprintf(stderr, "%s\n", obs.error().message.c_str()), 1;
    queries.push_back({std::move(*obs), truth_x[f]});
  }
  if (queries.empty()) return std::fprintf(stderr, "camera %s has no frames\n", x.c_str()), 1;
  std::printf("queries: camera %s frames %lld-%lld (%s observations), %d keypoints in the first\n",
              x.c_str(), static_cast<long long>(queries.front().obs.frame),
              static_cast<long long>(queries.back().obs.frame), observations.c_str(),
              queries.front().obs.features.size());

  FrameRegistrationOptions exact_options;
  exact_options.match = ExactMatching();
  std::vector<FrameRegistrationOptions> approximate_options;
  for (const int c : checks) {
    FrameRegistrationOptions o;  // the default: MapMatching()
    o.match.kd_trees = kd_trees;
    o.match.kd_tree_checks = c;
    if (!o.match.Check()) return std::fputs(kUsage, stderr), 2;
    approximate_options.push_back(o);
  }
  std::printf("approximate: kd-forest of %d trees, leaves searched %s (MapMatching: %d trees, %d "
              "leaves); exact: brute force; threads %s\n",
              kd_trees, [&] {
                std::string l;
                for (const int c : checks) l += (l.empty() ? "" : ",") + std::to_string(c);
                return l;
              }().c_str(), MapMatching().kd_trees, MapMatching().kd_tree_checks,
              threads > 0 ? std::to_string(threads).c_str() : "all");
  std::string summary;
  for (const int wanted : sizes) {
    ReferenceMap map = *full;
    if (wanted > 0 && static_cast<std::size_t>(wanted) < map.points.size())
      map.points.resize(static_cast<std::size_t>(wanted));
    t = Now();
    const MapIndex index = MapIndex::Of(map);
    const double copy_s = Now() - t;
    t = Now();
    index.descriptors->Prepare(kd_trees);
    const double build_s = Now() - t;
    std::printf("map of %d points (asked %d): index %.1f ms (descriptor copy %.1f ms, kd-forest "
                "%.1f ms, once per map)\n",
                index.size(), wanted, 1e3 * (copy_s + build_s), 1e3 * copy_s, 1e3 * build_s);
    std::vector<std::set<std::pair<int, int>>> exact_sets;
    for (const Query& q : queries) {
      std::set<std::pair<int, int>> s;
      for (const Match& m : MatchDescriptors(q.obs.features.descriptors.data(),
                                             q.obs.features.size(), *index.descriptors,
                                             exact_options.match))
        s.insert({m.query, m.train});
      exact_sets.push_back(std::move(s));
    }
    const int n = static_cast<int>(queries.size());
    const Row exact = Measure(index, camera_x, queries, exact_options, exact_sets, repeat);
    PrintRow("exact", exact, n);
    Row approximate;
    for (const FrameRegistrationOptions& o : approximate_options) {
      approximate = Measure(index, camera_x, queries, o, exact_sets, repeat);
      PrintRow(("checks " + std::to_string(o.match.kd_tree_checks)).c_str(), approximate, n);
    }
    const double ratio = exact.total_ms / std::max(approximate.total_ms, 1e-9);
    std::printf("  ratio exact / approximate (match+pnp): %.2fx; approximate match+pnp %.1f ms "
                "(gate <= 50 ms at 100000 points)\n",
                ratio, approximate.total_ms);
    char line[256];
    std::snprintf(line, sizeof line,
                  "largest map %d points: approximate %.1f ms, exact %.1f ms per frame "
                  "(match+pnp), ratio %.2fx, recall %.3f\n",
                  index.size(), approximate.total_ms, exact.total_ms, ratio, approximate.recall);
    summary = line;
  }
  std::fputs(summary.c_str(), stdout);
  std::printf("load average after: %s\n", LoadAverage().c_str());
  if (!tmp.empty()) {
    if (keep) std::printf("kept %s\n", tmp.c_str());
    else fs::remove_all(tmp);
  }
  return 0;
}
