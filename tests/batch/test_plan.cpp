// The plan file (batch/plan.h), shards, --per and the planner
// (batch/planner.h) over a dataset made of file names only: discovery opens
// no frame, so empty files in the LiFMCR layout are a dataset to it.

#include "batch/manifest.h"
#include "batch/plan.h"
#include "batch/planner.h"
#include "replay/layout.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <set>

namespace lifmcr::batch {
namespace {

namespace fs = std::filesystem;

// ROOT/00_Scene/Seq_A and Seq_B, cameras 111 and 222 with frames 0..frames-1.
fs::path MakeDataset(const fs::path& root, int frames) {
  for (const char* seq : {"Seq_A", "Seq_B"}) {
    const fs::path dir = root / "00_Scene" / seq;
    fs::create_directories(dir / "Vicon");
    test::WriteFile(dir / "Vicon" / layout::ViconCsvFileName(1), "");
    for (const char* serial : {"111", "222"}) {
      fs::create_directories(layout::CameraDir(dir, serial));
      for (int f = 0; f < frames; ++f) test::WriteFile(layout::RawFramePath(dir, serial, f), "");
    }
  }
  fs::create_directories(root / "Calibration" / "02_MLA_Calibration");
  return root;
}

TEST(Plan, FormatParsesBack) {
  Plan plan;
  plan.stage = Stage::kRegister;
  plan.per = "camera";
  plan.dataset = "/data/x";
  plan.planned_by = "lifmcr batch plan /data/x --stage register";
  Unit u;
  u.id = "S/Q/222";
  u.scene = "S";
  u.sequence = "Q";
  u.camera = "222";
  u.command = {"lifmcr", "register",      "/data/x/S/Q", "--camera", "222",
               "--out",  "units/S/Q/222", "--note",      "it's"};
  u.outputs = "units/S/Q/222";
  u.writes = {"units/S/Q/222/registration.csv"};
  u.needs = {{"/plans/cal", "S/Q/111"}};
  plan.units.push_back(u);
  const std::string text = FormatPlan(plan);
  Expected<Plan> back = ParsePlan(text, "plan.jsonl");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(FormatPlan(*back), text);
  EXPECT_EQ(back->units[0].needs[0].unit, "S/Q/111");
  EXPECT_EQ(back->units[0].CommandLine(),
            "lifmcr register /data/x/S/Q --camera 222 --out units/S/Q/222 --note 'it'\\''s'");
}

// A manifest entry parses back to the same text; one written before
// `cpu_seconds` existed reads with 0 there (it stays valid: its unit is not redone).
TEST(Manifest, EntryParsesBack) {
  ManifestEntry e;
  e.unit = "S/Q/111/000000-000001";
  e.state = UnitState::kDone;
  e.log = LogPathOf(e.unit);
  e.seconds = 2.5;
  e.cpu_seconds = 2.25;
  e.peak_rss_kib = 1024;
  e.host = "node1";
  e.shard = "0/2";
  e.finished_utc = "2026-12-06T10:41:07Z";
  e.outputs = {{"units/S/Q/111/000000-000001/a.tiff", 123, "0123456789abcdef"}};
  const std::string text = FormatManifestEntry(e);
  Expected<ManifestEntry> back = ParseManifestEntry(text, "entry");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(FormatManifestEntry(*back), text);
  EXPECT_EQ(back->cpu_seconds, 2.25);

  std::string older = text;
  const std::size_t at = older.find("\"cpu_seconds\"");
  ASSERT_NE(at, std::string::npos);
  older.erase(at, older.find('\n', at) + 1 - at);
  Expected<ManifestEntry> old = ParseManifestEntry(older, "entry");
  ASSERT_TRUE(old) << old.error().message << "\n" << older;
  EXPECT_EQ(old->cpu_seconds, 0);
  EXPECT_EQ(old->seconds, 2.5);
}

TEST(Plan, ErrorsNameTheLineAndField) {
  Plan plan;
  plan.per = "frames:2";
  plan.dataset = "/d";
  Unit u;
  u.id = "S/Q/1/000000-000001";
  u.command = {"lifmcr", "depth"};
  u.outputs = "units/" + u.id;
  plan.units = {u};
  const std::string good = FormatPlan(plan);
  auto error_of = [](const std::string& text) {
    Expected<Plan> p = ParsePlan(text, "P/plan.jsonl");
    return p ? std::string("parsed") : p.error().message;
  };
  EXPECT_EQ(error_of(good), "parsed");
  // Cut short: the last line has no newline.
  EXPECT_NE(error_of(good.substr(0, good.size() - 5)).find("P/plan.jsonl:2: the last line"),
            std::string::npos);
  // One unit line lost: the header's count says so.
  EXPECT_NE(error_of(good.substr(0, good.find('\n') + 1))
                .find("the header says 1 units, the file lists 0"),
            std::string::npos);
  auto replaced = [&](const std::string& from, const std::string& to) {
    return error_of(test::ReplaceFirst(good, from, to));
  };
  EXPECT_NE(replaced("\"units/S/Q/1/000000-000001\"", "\"units/S\"")
                .find("P/plan.jsonl:2: \"outputs\": expected"),
            std::string::npos);
  EXPECT_NE(
      replaced("\"unit\":\"S/Q/1/000000-000001\"", "\"unit\":\"S/../x\"").find(":2: \"unit\""),
      std::string::npos);
  EXPECT_NE(replaced("[\"lifmcr\",", "[\"rm\",").find(":2: \"command\": expected a lifmcr command"),
            std::string::npos);
  EXPECT_NE(replaced("\"lifmcr_batch_plan\":1", "\"lifmcr_batch_plan\":7")
                .find(":1: \"lifmcr_batch_plan\": version 7"),
            std::string::npos);
  EXPECT_NE(replaced("\"needs\":[]", "\"needs\":[{\"plan\":\"rel\",\"unit\":\"a\"}]")
                .find(":2: \"needs\""),
            std::string::npos);
  EXPECT_NE(replaced("{\"camera\"", "[").find(":2: expected one JSON object"), std::string::npos);
}

TEST(Plan, ShardsPartitionTheUnits) {
  Plan plan;
  plan.units.resize(11);
  for (int n = 1; n <= 5; ++n) {
    std::multiset<std::size_t> seen;
    for (int i = 0; i < n; ++i)
      for (std::size_t k : plan.ShardUnits(i, n)) {
        EXPECT_EQ(static_cast<int>(k % n), i);
        seen.insert(k);
      }
    EXPECT_EQ(seen.size(), 11u);
    EXPECT_EQ(std::set<std::size_t>(seen.begin(), seen.end()).size(), 11u) << n << " shards";
  }
  EXPECT_TRUE(ShardSpec::Parse("3/4"));
  EXPECT_EQ(ShardSpec::Parse("3/4")->index, 3);
  for (const char* bad : {"4/4", "-1/4", "1/0", "1", "/2", "1/", "a/2", "1/2x", "0/100001"}) {
    Expected<ShardSpec> s = ShardSpec::Parse(bad);
    ASSERT_FALSE(s) << bad;
    test::ExpectMessageHas(s.error(), {"--shard", bad, "0 <= I < N"});
  }
}

TEST(Plan, PerAndOptionsChecked) {
  EXPECT_EQ(PerSpec::Parse("frames:8")->frames, 8);
  EXPECT_FALSE(PerSpec::Parse("frames:0"));
  EXPECT_FALSE(PerSpec::Parse("frames:"));
  EXPECT_FALSE(PerSpec::Parse("lens"));
  PlanOptions o;
  o.dataset = "/d";
  o.out = "/p";
  EXPECT_TRUE(o.Check());
  o.per = "sequence";
  test::ExpectMessageHas(o.Check().error(),
                         {"--per sequence", "--stage depth", "frames:N or camera"});
  o.per = "";
  o.reference = "/map";
  test::ExpectMessageHas(o.Check().error(), {"--reference", "--stage depth", "register"});
  o.reference = "";
  o.extra = {"--out", "x"};
  test::ExpectMessageHas(o.Check().error(), {"--out", "PLAN_DIR"});
  o.extra = {};
  o.stage = Stage::kRegister;
  test::ExpectMessageHas(o.Check().error(), {"exactly one of --reference"});
  o.reference_from_ground_truth = true;
  EXPECT_TRUE(o.Check());
  o.stage = Stage::kEvaluate;
  test::ExpectMessageHas(o.Check().error(), {"--reference-from-ground-truth", "--stage evaluate"});
  o.reference_from_ground_truth = false;
  test::ExpectMessageHas(o.Check().error(), {"--registration-plan"});
  o.stage = Stage::kDepth;
  o.cameras = {"a_b"};
  test::ExpectMessageHas(o.Check().error(), {"--camera 'a_b'", "serial"});
}

TEST(Plan, DepthUnitsCoverEveryFrameOfEveryCameraOnce) {
  test::TempDir dir;
  const fs::path root = MakeDataset(dir / "data", 7);
  PlanOptions o;
  o.dataset = root.string();
  o.out = (dir / "plan").string();
  o.per = "frames:3";
  o.extra = {"--no-white"};
  Expected<Plan> plan = MakePlan(o);
  ASSERT_TRUE(plan) << plan.error().message;
  // 2 sequences x 2 cameras x ceil(7/3).
  ASSERT_EQ(plan->units.size(), 12u);
  const Unit& u = plan->units[2];
  EXPECT_EQ(u.id, "00_Scene/Seq_A/111/000006-000006");
  const std::vector<std::string> expected = {"lifmcr",
                                             "depth",
                                             fs::weakly_canonical(root / "00_Scene/Seq_A").string(),
                                             "--camera",
                                             "111",
                                             "--out",
                                             "units/00_Scene/Seq_A/111/000006-000006",
                                             "--frame",
                                             "6",
                                             "--no-white"};
  EXPECT_EQ(u.command, expected);
  EXPECT_EQ(u.writes.size(), 8u);  // no intrinsics: no metric depth or cloud
  EXPECT_EQ(u.writes[0], "units/00_Scene/Seq_A/111/000006-000006/111_000006_virtual_depth.tiff");
  std::set<std::string> frames;
  for (const Unit& unit : plan->units)
    for (std::size_t k = 1 + std::find(unit.command.begin(), unit.command.end(), "--frame") -
                         unit.command.begin();
         k < unit.command.size() && unit.command[k] != "--no-white"; ++k)
      EXPECT_TRUE(frames.insert(unit.scene + unit.sequence + unit.camera + unit.command[k]).second);
  EXPECT_EQ(frames.size(), 2u * 2u * 7u);

  o.per = "camera";
  o.cameras = {"222"};
  o.sequences = {"00_Scene/Seq_B"};
  plan = MakePlan(o);
  ASSERT_TRUE(plan) << plan.error().message;
  ASSERT_EQ(plan->units.size(), 1u);
  EXPECT_EQ(plan->units[0].id, "00_Scene/Seq_B/222");
  EXPECT_NE(std::find(plan->units[0].command.begin(), plan->units[0].command.end(), "--all-frames"),
            plan->units[0].command.end());
  EXPECT_EQ(plan->units[0].writes.size(), 8u * 7u);

  o.dataset = (dir / "nowhere").string();
  plan = MakePlan(o);
  ASSERT_FALSE(plan);
  test::ExpectMessageHas(plan.error(),
                         {"nowhere", "expected a dataset root, a scene or a sequence"});
}

TEST(Plan, LaterStagesNeedTheEarlierPlansUnits) {
  test::TempDir dir;
  const fs::path root = MakeDataset(dir / "data", 2);
  PlanOptions cal;
  cal.dataset = root.string();
  cal.out = (dir / "cal").string();
  cal.stage = Stage::kCalibrate;
  Expected<Plan> cal_plan = MakePlan(cal);
  ASSERT_TRUE(cal_plan) << cal_plan.error().message;
  ASSERT_EQ(cal_plan->units.size(), 4u);
  ASSERT_TRUE(WritePlan(dir / "cal", *cal_plan));
  const std::string cal_dir = fs::weakly_canonical(dir / "cal").string();

  PlanOptions reg;
  reg.dataset = root.string();
  reg.out = (dir / "reg").string();
  reg.stage = Stage::kRegister;
  reg.per = "camera";
  reg.calibration_plan = (dir / "cal").string();
  Expected<Plan> reg_plan = MakePlan(reg);
  ASSERT_TRUE(reg_plan) << reg_plan.error().message;
  // Camera 111 is each sequence's reference: one unit per sequence, for 222.
  ASSERT_EQ(reg_plan->units.size(), 2u);
  const Unit& r = reg_plan->units[0];
  EXPECT_EQ(r.id, "00_Scene/Seq_A/222");
  ASSERT_EQ(r.needs.size(), 2u);
  EXPECT_EQ(r.needs[0].plan, cal_dir);
  EXPECT_EQ(r.needs[0].unit, "00_Scene/Seq_A/111");
  EXPECT_EQ(r.needs[1].unit, "00_Scene/Seq_A/222");
  const std::string cmd = r.CommandLine();
  EXPECT_NE(cmd.find("--reference " + cal_dir + "/units/00_Scene/Seq_A/111 --intrinsics " +
                     cal_dir + "/units/00_Scene/Seq_A/111/intrinsics.yaml --intrinsics " + cal_dir +
                     "/units/00_Scene/Seq_A/222/intrinsics.yaml"),
            std::string::npos)
      << cmd;
  ASSERT_TRUE(WritePlan(dir / "reg", *reg_plan));

  PlanOptions ev;
  ev.dataset = root.string();
  ev.out = (dir / "ev").string();
  ev.stage = Stage::kEvaluate;
  ev.registration_plan = (dir / "reg").string();
  ev.calibration_plan = (dir / "cal").string();
  Expected<Plan> ev_plan = MakePlan(ev);
  ASSERT_TRUE(ev_plan) << ev_plan.error().message;
  ASSERT_EQ(ev_plan->units.size(), 2u);
  EXPECT_EQ(ev_plan->units[1].id, "00_Scene/Seq_B");
  EXPECT_EQ(ev_plan->units[1].needs.size(), 2u);
  EXPECT_NE(ev_plan->units[1].CommandLine().find("--reference-poses " + cal_dir +
                                                 "/units/00_Scene/Seq_B/111/poses_111.csv"),
            std::string::npos);
  // evaluate's camera 0 is the register plan's, whatever evaluate's own default.
  EXPECT_EQ(reg_plan->units[1].reference, "111");
  EXPECT_EQ(ev_plan->units[1].reference, "111");
  EXPECT_NE(ev_plan->units[1].CommandLine().find("--reference 111"), std::string::npos);

  // A map folder names its camera in its intrinsics.yaml: that camera gets no unit.
  lifmcr::test::WriteFile(dir / "map/intrinsics.yaml", "cameras:\n  - serial: \"222\"\n");
  reg.calibration_plan.clear();
  reg.reference = (dir / "map").string();
  reg.out = (dir / "reg2").string();
  reg_plan = MakePlan(reg);
  ASSERT_TRUE(reg_plan) << reg_plan.error().message;
  ASSERT_EQ(reg_plan->units.size(), 2u);
  EXPECT_EQ(reg_plan->units[0].id, "00_Scene/Seq_A/111");
  EXPECT_EQ(reg_plan->units[0].reference, "222");

  // A plan of the wrong stage is named as such.
  ev.registration_plan = (dir / "cal").string();
  ev_plan = MakePlan(ev);
  ASSERT_FALSE(ev_plan);
  test::ExpectMessageHas(ev_plan.error(),
                         {"--registration-plan", "a calibrate plan, expected a register plan"});
}

TEST(Plan, CliRefusesBadCommandsAndAnotherPlanInTheFolder) {
  test::TempDir dir;
  const fs::path root = MakeDataset(dir / "data", 3);
  const std::string plan =
      "batch plan " + root.string() + " --stage depth --out " + (dir / "plan").string();
  test::CommandResult first = test::RunLifmcr(plan + " --per frames:2");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_NE(first.out.find("depth plan of " + fs::weakly_canonical(root).string() +
                           ": 8 units per frames:2"),
            std::string::npos)
      << first.out;
  // The same units again: nothing changes.
  test::CommandResult again = test::RunLifmcr(plan + " --per frames:2");
  EXPECT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.out.find("unchanged"), std::string::npos) << again.out;
  // Other units into the same folder: refused, the plan kept.
  test::CommandResult other = test::RunLifmcr(plan + " --per frames:1");
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.err.find("holds another plan"), std::string::npos) << other.err;
  EXPECT_EQ(ReadPlan(dir / "plan")->per, "frames:2");
  // A word after -- that the stage does not take: refused before anything is written.
  test::CommandResult bogus =
      test::RunLifmcr("batch plan " + root.string() + " --stage depth --out " +
                      (dir / "p2").string() + " -- --bogus");
  EXPECT_EQ(bogus.exit_code, 2);
  EXPECT_NE(bogus.err.find("lifmcr depth refuses its command"), std::string::npos) << bogus.err;
  EXPECT_NE(bogus.err.find("--bogus"), std::string::npos) << bogus.err;
  EXPECT_FALSE(fs::exists(dir / "p2/plan.jsonl"));
  test::CommandResult per =
      test::RunLifmcr("batch plan " + root.string() + " --stage calibrate --per frames:4 --out " +
                      (dir / "p3").string());
  EXPECT_EQ(per.exit_code, 2);
  EXPECT_NE(per.err.find("--per frames:4 does not apply to --stage calibrate"), std::string::npos)
      << per.err;
  // status before any run: every unit left.
  test::CommandResult status = test::RunLifmcr("batch status " + (dir / "plan").string());
  EXPECT_EQ(status.exit_code, 3);
  EXPECT_NE(status.out.find("8 units: 0 done, 0 failed, 8 left"), std::string::npos) << status.out;
}

}  // namespace
}  // namespace lifmcr::batch
