// `lifmcr evaluate` end to end on a synthetic rig written without images
// (`lifmcr synth --no-images`): 200 frames of poses, Vicon at 80 Hz with
// marker noise and occlusion gaps. The registration input is made here from
// the ground truth poses plus realistic registration noise (1 mm and 0.05
// deg per axis, 2 % gross failures, 2 % frames not registered) — legitimate
// for testing the evaluation, which must see through that noise; the
// registration itself is tested by its own suite.
//
// Gates (issue 14): hand-eye offsets within 2 mm / 0.2 deg of the truth;
// absolute error after the correction not above the relative error; without
// the correction the absolute error is the one the true offsets cause.
#include "evaluation/evaluation_inputs.h"
#include "registration/map/poses_csv.h"
#include "evaluation/trajectory_metrics.h"
#include "replay/layout.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180.0;
const std::string kCam0 = "40398678", kCamX = "40398673";

Pose Noise(std::mt19937_64& rng, double sigma_deg, double sigma_mm) {
  std::normal_distribution<double> n(0, 1);
  const Eigen::Vector3d w(n(rng), n(rng), n(rng));
  Pose p = Pose::Identity();
  p.linear() = Eigen::AngleAxisd(sigma_deg * kDeg * w.norm(), w.normalized()).toRotationMatrix();
  p.translation() = sigma_mm * Eigen::Vector3d(n(rng), n(rng), n(rng));
  return p;
}

// c0_from_cx of every frame from the ground truth poses of a synthetic sequence.
FramePoses TrueExtrinsics(const fs::path& seq) {
  FramePoses truth;
  auto w0 = registration::ReadPosesCsv(layout::PosesCsvPath(seq, kCam0));
  auto wx = registration::ReadPosesCsv(layout::PosesCsvPath(seq, kCamX));
  if (!w0 || !wx || w0->size() != wx->size()) return truth;
  for (std::size_t k = 0; k < w0->size(); ++k)
    truth[(*w0)[k].frame] = (*w0)[k].world_from_cam.inverse() * (*wx)[k].world_from_cam;
  return truth;
}

// Registration rows of pnp and ransac: the truth with 1 mm / 0.05 deg noise,
// 2 % failures (a status) and 2 % wrong poses (3 deg / 40 mm).
std::vector<RegistrationRow> NoisyRegistration(const FramePoses& truth, std::uint64_t seed) {
  std::vector<RegistrationRow> rows;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (const std::string method : {"pnp", "ransac"}) {
    for (const auto& [f, c0_from_cx] : truth) {
      RegistrationRow row;
      row.frame = f;
      row.camera = kCamX;
      row.method = method;
      row.inliers = 300;
      row.rmse_px = 0.4;
      row.status = "ok";
      const double draw = u(rng);
      if (draw < 0.02) {
        row.status = "too few matches";
      } else if (draw < 0.04) {
        row.c0_from_cx = c0_from_cx * Noise(rng, 3.0, 40.0);  // a wrong registration
      } else {
        row.c0_from_cx = c0_from_cx * Noise(rng, 0.05, 1.0);
      }
      rows.push_back(row);
    }
  }
  return rows;
}

class EvaluateCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    test::WriteFile(*dir_ / "synth.yaml",
                    "rig:\n  speed_scale: 5\nvicon:\n  marker_noise_mm: 0.15\n  occlusion_gaps: 3\n");
    const test::CommandResult synth = test::RunLifmcr(
        "synth --out " + (*dir_ / "data").string() + " --frames 200 --no-images --quiet --config " +
        (*dir_ / "synth.yaml").string());
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    seq_ = new fs::path(*dir_ / "data" / "00_Synthetic" / "Sequence_00");
    ASSERT_FALSE(fs::exists(layout::CameraDir(*seq_, kCam0)));  // no images written
    truth_ = new FramePoses(TrueExtrinsics(*seq_));
    ASSERT_FALSE(truth_->empty());
    x0_ = new Pose(*ReadMarkerFromCamCsv(layout::MarkerFromCamCsvPath(*seq_, kCam0)));
    xx_ = new Pose(*ReadMarkerFromCamCsv(layout::MarkerFromCamCsvPath(*seq_, kCamX)));
    const std::vector<RegistrationRow> rows = NoisyRegistration(*truth_, 11);
    test::WriteFile(*dir_ / "registration.csv", FormatRegistrationCsv(rows));
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete seq_;
    delete truth_;
    delete x0_;
    delete xx_;
  }
  static nlohmann::json ReadJson(const fs::path& path) {
    return nlohmann::json::parse(test::ReadFile(path));
  }

  static test::TempDir* dir_;
  static fs::path* seq_;
  static FramePoses* truth_;
  static Pose *x0_, *xx_;
};
test::TempDir* EvaluateCli::dir_ = nullptr;
fs::path* EvaluateCli::seq_ = nullptr;
FramePoses* EvaluateCli::truth_ = nullptr;
Pose* EvaluateCli::x0_ = nullptr;
Pose* EvaluateCli::xx_ = nullptr;

TEST_F(EvaluateCli, HandEyeGatesOn200FramesWithRealisticNoise) {
  const fs::path out = *dir_ / "eval";
  const test::CommandResult r = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::cout << r.out;
  EXPECT_NE(r.err.find("evaluate: "), std::string::npos);  // progress on stderr
  std::istringstream progress(r.err);
  for (std::string line; std::getline(progress, line);)
    if (line.find("hand-eye:") != std::string::npos || line.find("plate") != std::string::npos)
      std::cout << line << "\n";
  const nlohmann::json j = ReadJson(out / "evaluation.json");
  ASSERT_EQ(j["evaluations"].size(), 2u);
  for (const nlohmann::json& e : j["evaluations"]) {
    SCOPED_TRACE(e["method"].get<std::string>());
    ASSERT_EQ(e["correction"]["source"], "estimated") << e["correction"]["note"];
    for (const std::string& serial : {kCam0, kCamX}) {
      const auto& err = e["correction"]["error_vs_truth"][serial];
      std::cout << e["method"] << " " << serial << ": marker_from_cam off the truth by "
                << err["translation_mm"] << " mm, " << err["rotation_deg"] << " deg\n";
      EXPECT_LT(err["translation_mm"].get<double>(), 2.0);
      EXPECT_LT(err["rotation_deg"].get<double>(), 0.2);
    }
    const auto& corrected = e["corrected"];
    EXPECT_LE(corrected["ape"]["translation_mm"]["rmse"].get<double>(),
              corrected["rpe"]["translation_mm"]["rmse"].get<double>());
    EXPECT_LE(corrected["ape"]["rotation_deg"]["rmse"].get<double>(),
              corrected["rpe"]["rotation_deg"]["rmse"].get<double>());
    // Without the correction: the error the true offsets cause,
    // E = c0_from_cx^-1 X0 c0_from_cx XX^-1, over the same frames.
    std::vector<double> expected;
    for (const auto& [f, c] : *truth_)
      expected.push_back((c.inverse() * *x0_ * c * xx_->inverse()).translation().norm());
    const ErrorStats offset = ErrorStats::Of(expected);
    const double uncorrected = e["uncorrected"]["ape"]["translation_mm"]["rmse"];
    const double median = e["uncorrected"]["ape"]["translation_mm"]["median"];
    const double corrected_median = corrected["ape"]["translation_mm"]["median"];
    std::cout << "uncorrected absolute RMSE " << uncorrected << " mm (median " << median
              << "), caused by the true offsets " << offset.rmse << " mm (median " << offset.median
              << "); corrected " << corrected["ape"]["translation_mm"]["rmse"].get<double>()
              << " mm (median " << corrected_median << ")\n";
    EXPECT_GT(offset.rmse, 20.0);  // tens of mm, as in the paper
    // The 4 % wrong registrations add to the RMSE; the median shows the offset alone.
    EXPECT_NEAR(uncorrected, offset.rmse, 0.1 * offset.rmse);
    EXPECT_NEAR(median, offset.median, 0.05 * offset.median + 1.0);
    EXPECT_LT(corrected_median, 3.0);
    // 2 % failures were rows with a status, counted, not evaluated.
    EXPECT_GT(e["failed"].get<int>(), 0);
  }
  // Occlusion gaps: frames without Vicon are counted and left out.
  std::size_t untracked = 0;
  for (const nlohmann::json& c : j["cameras"]) untracked += c["untracked_frames"].size();
  EXPECT_GT(untracked, 0u);
  EXPECT_GT(j["evaluations"][0]["without_truth"].get<int>(), 0);
  EXPECT_EQ(j["plate_alignment"].value("done", true), true);
  EXPECT_LT(j["plate_alignment"]["marker_fit_rms_mm"].get<double>(), 1.0);
  EXPECT_EQ(j["method_differences"].size(), 1u);
  // The files a person and evo read.
  for (const std::string f :
       {"evaluation.md", "hand_eye.yaml", "tum/40398673_c0_from_cx_vicon.txt",
        "tum/pnp_40398673_c0_from_cx.txt", "tum/pnp_40398673_c0_from_cx_vicon_corrected.txt",
        "plots/trajectories_top.png", "plots/pnp_40398673_errors.png",
        "plots/ransac_40398673_axis_histograms.png"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  std::istringstream tum(test::ReadFile(out / "tum/pnp_40398673_c0_from_cx.txt"));
  std::string line;
  std::getline(tum, line);
  std::istringstream fields(line);
  int count = 0;
  for (std::string field; fields >> field;) ++count;
  EXPECT_EQ(count, 8) << line;
  const std::string md = test::ReadFile(out / "evaluation.md");
  for (const std::string part : {"Relative errors", "Absolute errors", "per camera axis",
                                 "Differences between the methods", "hand-eye corrected"})
    EXPECT_NE(md.find(part), std::string::npos) << part;

  // The estimate read back as a split by sequence (--hand-eye FILE) gives the same offsets.
  const test::CommandResult again = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --out " + (*dir_ / "eval2").string() + " --hand-eye " + (out / "hand_eye.yaml").string() +
      " --no-plots --quiet");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const nlohmann::json j2 = ReadJson(*dir_ / "eval2" / "evaluation.json");
  EXPECT_EQ(j2["evaluations"][0]["correction"]["source"], "given");
  EXPECT_NEAR(j2["evaluations"][0]["correction"]["marker_from_cam"]["tx_mm"].get<double>(),
              j["evaluations"][0]["correction"]["marker_from_cam"]["tx_mm"].get<double>(), 1e-4);
}

// --split sequence: a second sequence of the same rig (same seed, so the
// same marker clusters and offsets; another motion amplitude) gives the
// offsets, which correct every frame of the first: within the gates of
// the issue, and nothing fit to the frames it corrects.
TEST_F(EvaluateCli, SplitBySequenceEstimatesOnOneSequenceAndCorrectsTheOther) {
  test::WriteFile(*dir_ / "synth_b.yaml",
                  "rig:\n  speed_scale: 4\n  sequence: Sequence_01\nvicon:\n  marker_noise_mm: 0.15\n");
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (*dir_ / "data").string() + " --frames 200 --no-images --quiet --config " +
      (*dir_ / "synth_b.yaml").string());
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq_b = *dir_ / "data" / "00_Synthetic" / "Sequence_01";
  ASSERT_EQ(test::ReadFile(layout::MarkerFromCamCsvPath(seq_b, kCamX)),
            test::ReadFile(layout::MarkerFromCamCsvPath(*seq_, kCamX)));  // the same rig
  const FramePoses truth_b = TrueExtrinsics(seq_b);
  ASSERT_FALSE(truth_b.empty());
  test::WriteFile(*dir_ / "registration_b.csv", FormatRegistrationCsv(NoisyRegistration(truth_b, 12)));

  const fs::path out = *dir_ / "eval_split_sequence";
  const test::CommandResult r = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --split sequence --hand-eye-from " + seq_b.string() + " --hand-eye-registration " +
      (*dir_ / "registration_b.csv").string() + " --no-plots --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("split sequence: estimating the hand-eye offsets on"), std::string::npos);
  EXPECT_NE(r.out.find("hand-eye"), std::string::npos);  // the table, printed once
  EXPECT_EQ(r.out.find("method camera"), r.out.rfind("method camera")) << r.out;
  EXPECT_TRUE(fs::exists(out / "hand_eye_source" / "evaluation.md"));
  const nlohmann::json j = ReadJson(out / "evaluation.json");
  EXPECT_EQ(j["settings"]["split"], "sequence");
  EXPECT_EQ(j["settings"]["hand_eye_from"], seq_b.string());
  ASSERT_EQ(j["evaluations"].size(), 2u);
  for (const nlohmann::json& e : j["evaluations"]) {
    SCOPED_TRACE(e["method"].get<std::string>());
    ASSERT_EQ(e["correction"]["source"], "given") << e["correction"]["note"];
    for (const std::string& serial : {kCam0, kCamX}) {
      const auto& err = e["correction"]["error_vs_truth"][serial];
      std::cout << "split sequence, " << e["method"] << " " << serial << ": offsets from "
                << "Sequence_01 off the truth by " << err["translation_mm"] << " mm, "
                << err["rotation_deg"] << " deg\n";
      EXPECT_LT(err["translation_mm"].get<double>(), 2.0);
      EXPECT_LT(err["rotation_deg"].get<double>(), 0.2);
    }
    const auto& corrected = e["corrected"];
    std::cout << "  corrected absolute RMSE " << corrected["ape"]["translation_mm"]["rmse"]
              << " mm (median " << corrected["ape"]["translation_mm"]["median"]
              << "), uncorrected " << e["uncorrected"]["ape"]["translation_mm"]["rmse"] << " mm\n";
    EXPECT_LT(corrected["ape"]["translation_mm"]["median"].get<double>(), 3.0);
    EXPECT_GT(e["uncorrected"]["ape"]["translation_mm"]["median"].get<double>(), 20.0);
  }
  const std::string md = test::ReadFile(out / "evaluation.md");
  EXPECT_NE(md.find("split sequence"), std::string::npos);

  // Usage errors: the split without its inputs, or with the same sequence.
  test::CommandResult bad = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --split sequence --out " + (*dir_ / "bad").string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--hand-eye-from"), std::string::npos) << bad.err;
  bad = test::RunLifmcr("evaluate " + seq_->string() + " --registration " +
                        (*dir_ / "registration.csv").string() + " --split sequence --hand-eye-from " +
                        seq_->string() + " --hand-eye-registration " +
                        (*dir_ / "registration.csv").string() + " --out " + (*dir_ / "bad").string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("itself"), std::string::npos) << bad.err;
  bad = test::RunLifmcr("evaluate " + seq_->string() + " --registration " +
                        (*dir_ / "registration.csv").string() + " --hand-eye-from " +
                        seq_b.string() + " --out " + (*dir_ / "bad").string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("go with --split sequence"), std::string::npos) << bad.err;
}

TEST_F(EvaluateCli, TrueOffsetsLeaveOnlyTheRegistrationNoise) {
  const fs::path out = *dir_ / "eval_truth";
  const test::CommandResult r = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --out " + out.string() + " --hand-eye truth --no-plots --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = ReadJson(out / "evaluation.json");
  // Registration noise 1 mm per axis: median |t| about 1.5 mm, Vicon adds a
  // little. In rotation Vicon dominates: 0.15 mm of marker noise on two
  // clusters of about 100 x 60 mm turns marker0_from_markerX by about 0.2 deg.
  const auto& ape = j["evaluations"][0]["corrected"]["ape"];
  std::cout << "true offsets: absolute error median " << ape["translation_mm"]["median"]
            << " mm, " << ape["rotation_deg"]["median"] << " deg\n";
  EXPECT_LT(ape["translation_mm"]["median"].get<double>(), 2.5);
  EXPECT_LT(ape["rotation_deg"]["median"].get<double>(), 0.3);
}

TEST_F(EvaluateCli, MapFramePosesShowEachCamerasOffsetAndCorrectIt) {
  // Camera 0's poses in the map as lifmcr calibrate writes them (here: the
  // truth with 1 mm / 0.05 deg noise; the map frame is the plate frame).
  std::mt19937_64 rng(21);
  auto w0 = registration::ReadPosesCsv(layout::PosesCsvPath(*seq_, kCam0));
  ASSERT_TRUE(w0);
  for (registration::FramePose& p : *w0) p.world_from_cam = p.world_from_cam * Noise(rng, 0.05, 1.0);
  ASSERT_TRUE(registration::WritePosesCsv(*dir_ / "w0_from_c0.csv", *w0));
  const fs::path out = *dir_ / "eval_map";
  const test::CommandResult r = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --reference-poses " + (*dir_ / "w0_from_c0.csv").string() + " --out " + out.string() +
      " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::cout << r.out;
  const nlohmann::json j = ReadJson(out / "evaluation.json");
  ASSERT_EQ(j["map_frame_evaluations"].size(), 3u);  // camera 0, camera X by pnp and ransac
  const nlohmann::json& c0 = j["map_frame_evaluations"][0];
  EXPECT_EQ(c0["camera"], kCam0);
  // Without correction the error is the offset itself: E = cam_from_marker,
  // |t| = |t(X0^-1)| in every frame (the paper's supplementary), in the
  // camera frame per axis.
  const Eigen::Vector3d offset = x0_->inverse().translation();
  const auto& axes = c0["uncorrected"]["ape"]["translation_axis_mm"];
  std::cout << "camera 0 offset in its frame (" << offset.transpose() << ") mm, mean per-axis "
            << "error (" << axes["x"]["mean"] << ", " << axes["y"]["mean"] << ", "
            << axes["z"]["mean"] << ")\n";
  EXPECT_NEAR(axes["x"]["mean"].get<double>(), offset.x(), 1.0);
  EXPECT_NEAR(axes["y"]["mean"].get<double>(), offset.y(), 1.0);
  EXPECT_NEAR(axes["z"]["mean"].get<double>(), offset.z(), 1.0);
  const auto& err = c0["correction"]["error_vs_truth"][kCam0];
  std::cout << "camera 0 marker_from_cam from map poses off the truth by " << err["translation_mm"]
            << " mm, " << err["rotation_deg"] << " deg\n";
  EXPECT_LT(err["translation_mm"].get<double>(), 2.0);
  EXPECT_LT(err["rotation_deg"].get<double>(), 0.2);
  EXPECT_LT(c0["corrected"]["ape"]["translation_mm"]["median"].get<double>(), 3.0);
  EXPECT_NE(test::ReadFile(out / "evaluation.md").find("map (plate) frame"), std::string::npos);
  // Camera 0 and each method's camera X solved together with one plate
  // correction Z, held near the plate alignment's: every camera's offset
  // within the gate of the truth.
  EXPECT_FALSE(j["plate_alignment"]["z_prior"].get<std::string>().empty());
  for (const nlohmann::json& m : j["map_frame_evaluations"]) {
    const std::string camera = m["camera"];
    SCOPED_TRACE(m["method"].get<std::string>() + " " + camera);
    EXPECT_EQ(m["correction"]["source"], "joint map frame") << m["correction"]["note"];
    const auto& e = m["correction"]["error_vs_truth"][camera];
    std::cout << m["method"] << " " << camera << " joint map-frame marker_from_cam off the truth by "
              << e["translation_mm"] << " mm, " << e["rotation_deg"] << " deg\n";
    EXPECT_LT(e["translation_mm"].get<double>(), 2.0);
    EXPECT_LT(e["rotation_deg"].get<double>(), 0.2);
  }
  // 200 frames turning tens of degrees determine Z from the motions alone.
  const test::CommandResult free = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "registration.csv").string() +
      " --reference-poses " + (*dir_ / "w0_from_c0.csv").string() + " --out " +
      (*dir_ / "eval_map_free").string() + " --plate-correction free --no-plots --quiet");
  ASSERT_EQ(free.exit_code, 0) << free.err;
  const nlohmann::json jf = ReadJson(*dir_ / "eval_map_free" / "evaluation.json");
  EXPECT_NE(jf["plate_alignment"]["z_prior"].get<std::string>().find("free"), std::string::npos);
  const auto& ef = jf["map_frame_evaluations"][0]["correction"]["error_vs_truth"][kCam0];
  std::cout << "camera 0 marker_from_cam with Z free off the truth by " << ef["translation_mm"]
            << " mm, " << ef["rotation_deg"] << " deg\n";
  EXPECT_LT(ef["translation_mm"].get<double>(), 2.0);
  EXPECT_LT(ef["rotation_deg"].get<double>(), 0.2);
}

TEST_F(EvaluateCli, RefusesTheHandEyeForARigidPair) {
  // A rigidly mounted pair: c0_from_cx never changes, the offsets of the two
  // cameras cannot be told apart.
  std::vector<RegistrationRow> rows;
  for (const auto& [f, c] : *truth_) {
    RegistrationRow row;
    row.frame = f;
    row.camera = kCamX;
    row.method = "pnp";
    row.status = "ok";
    row.c0_from_cx = truth_->begin()->second;
    rows.push_back(row);
  }
  test::WriteFile(*dir_ / "rigid.csv", FormatRegistrationCsv(rows));
  const test::CommandResult r = test::RunLifmcr(
      "evaluate " + seq_->string() + " --registration " + (*dir_ / "rigid.csv").string() +
      " --out " + (*dir_ / "eval_rigid").string() + " --no-plots");
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("cannot determine"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(*dir_ / "eval_rigid" / "evaluation.md"));  // uncorrected tables still
}

TEST_F(EvaluateCli, BadInputsAreErrorsNamingTheFile) {
  test::WriteFile(*dir_ / "bad.csv",
                  "frame,camera,method,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz,inliers,rmse_px,status\n"
                  "0,40398673,pnp,1,2,3,2,0,0,0,10,0.5,ok\n");
  test::CommandResult r = test::RunLifmcr("evaluate " + seq_->string() + " --registration " +
                                          (*dir_ / "bad.csv").string() + " --out " +
                                          (*dir_ / "eval_bad").string() + " --quiet");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.csv:2"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("norm"), std::string::npos) << r.err;
  r = test::RunLifmcr("evaluate " + seq_->string() + " --out x");
  EXPECT_EQ(r.exit_code, 2);
  r = test::RunLifmcr("evaluate --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("Exit codes"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr
