// FrameSetAssembler on generated runs with known truth: every trigger is
// emitted exactly once and in order, each camera slot holds the right frame
// or lists the camera as missing, each set has its Vicon frame f0 + 8k or is
// marked without it, and every loss is counted by kind.
#include "sync/frame_set_assembler.h"
#include "tests/sync/rig_timeline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

namespace lifmcr {
namespace {

using test::Truth;

FrameSetAssemblerOptions OptionsFor(const test::Timeline& timeline, int cameras) {
  FrameSetAssemblerOptions options;
  for (int c = 0; c < cameras; ++c) options.serials.push_back("cam" + std::to_string(c));
  // Vicon frames arrive ~1 ms after the trigger, camera frames 2-5.5 ms.
  options.vicon_arrival_offset_ns = 1'250'000 - timeline.camera_latency_mean_ns;
  return options;
}

struct RunResult {
  std::vector<FrameSet> sets;
  DropCounter drops;
  std::vector<CameraSyncStats> stats;
  std::optional<std::int64_t> f0;
};

RunResult RunAssembler(const test::Timeline& timeline, FrameSetAssemblerOptions options) {
  EXPECT_TRUE(options.Check().ok());
  FrameSetAssembler assembler(std::move(options));
  RunResult result;
  auto take = [&](std::vector<FrameSet> sets) {
    for (FrameSet& set : sets) result.sets.push_back(std::move(set));
  };
  for (const test::Event& event : timeline.events) {
    take(assembler.Poll(event.host_ns));
    if (event.is_vicon) {
      assembler.AddVicon(event.vicon);
    } else {
      assembler.AddFrame(event.frame);
    }
    take(assembler.Poll(event.host_ns));
    EXPECT_LE(assembler.pending_triggers(), 12u);  // bounded by the lateness
  }
  take(assembler.Flush());
  result.drops = assembler.drops();
  result.stats = assembler.camera_stats();
  result.f0 = assembler.vicon_f0();
  return result;
}

void CheckAgainstTruth(const test::TimelineOptions& o, const test::Timeline& timeline,
                       const RunResult& result) {
  // The last trigger any camera delivered a frame for (on time or late).
  int last = 0;
  for (int c = 0; c < o.cameras; ++c)
    for (int k = 0; k < o.triggers; ++k)
      if (timeline.truth[c][k] != Truth::kNotExposed && timeline.truth[c][k] != Truth::kLost)
        last = std::max(last, k);
  ASSERT_EQ(result.sets.size(), static_cast<std::size_t>(last + 1));
  ASSERT_TRUE(result.f0.has_value());
  EXPECT_EQ(*result.f0, o.f0);
  std::uint64_t missed = 0, failed = 0, late = 0, vicon_missing = 0;
  for (int k = 0; k <= last; ++k) {
    const FrameSet& set = result.sets[k];
    ASSERT_EQ(set.trigger_index, k);
    ASSERT_EQ(set.frames.size(), static_cast<std::size_t>(o.cameras));
    std::map<int, std::string> missing;
    for (const MissingFrame& m : set.missing) missing[m.camera_index] = m.reason;
    for (int c = 0; c < o.cameras; ++c) {
      const Truth truth = timeline.truth[c][k];
      SCOPED_TRACE("trigger " + std::to_string(k) + " camera " + std::to_string(c));
      if (truth == Truth::kOk || truth == Truth::kFailed) {
        ASSERT_TRUE(set.frames[c].has_value());
        EXPECT_EQ(set.frames[c]->frame_id, timeline.frame_id[c][k]);
        EXPECT_EQ(missing.count(c), truth == Truth::kFailed ? 1u : 0u);
        failed += truth == Truth::kFailed;
      } else {
        EXPECT_FALSE(set.frames[c].has_value());
        ASSERT_EQ(missing.count(c), 1u);
        EXPECT_EQ(missing[c], "no frame for this trigger");
        ++missed;
        late += truth == Truth::kLate;
      }
    }
    ASSERT_EQ(set.vicon_frame, o.f0 + o.divider * k);
    const bool dropped = timeline.vicon_dropped[set.vicon_frame - timeline.first_vicon];
    EXPECT_EQ(set.vicon.has_value(), !dropped) << "trigger " << k;
    if (set.vicon) {
      EXPECT_EQ(set.vicon->vicon_frame, set.vicon_frame);
    }
    vicon_missing += dropped;
    EXPECT_EQ(set.complete(), set.missing.empty() && !dropped);
  }
  std::uint64_t vicon_gaps = 0;
  for (bool dropped : timeline.vicon_dropped) vicon_gaps += dropped;
  const DropCounter& d = result.drops;
  EXPECT_EQ(d[DropKind::kCameraMissedTrigger], missed);
  EXPECT_EQ(d[DropKind::kCameraFrameFailed], failed);
  EXPECT_EQ(d[DropKind::kLateFrame], late);
  EXPECT_EQ(d[DropKind::kFrameWithoutTrigger], static_cast<std::uint64_t>(timeline.spurious));
  EXPECT_EQ(d[DropKind::kViconGap], vicon_gaps);
  EXPECT_EQ(d[DropKind::kViconMissingForTrigger], vicon_missing);
  EXPECT_EQ(d[DropKind::kViconPhaseMismatch], 0u);
  EXPECT_EQ(d[DropKind::kClockJump], 0u);
  EXPECT_EQ(d[DropKind::kViconOutOfOrder], 0u);
  EXPECT_LE(d[DropKind::kCounterMismatch], static_cast<std::uint64_t>(timeline.spurious));
}

TEST(FrameSetAssembler, EveryTriggerOnceWithItsFramesOnGeneratedRuns) {
  for (unsigned seed = 1; seed <= 30; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    test::TimelineOptions o;
    o.seed = seed;
    o.cameras = 1 + static_cast<int>(seed % 4);
    const test::Timeline timeline = test::MakeTimeline(o);
    const RunResult result = RunAssembler(timeline, OptionsFor(timeline, o.cameras));
    CheckAgainstTruth(o, timeline, result);
    if (HasFatalFailure()) return;
  }
}

TEST(FrameSetAssembler, CleanRunIsCompleteAndCountersWrapQuietly) {
  test::TimelineOptions o;
  o.p_not_exposed = o.p_lost = o.p_failed = o.p_late = o.p_spurious = o.p_vicon_drop = 0.0;
  o.triggers = 400;  // the counters wrap at 65535 after 136 frames
  const test::Timeline timeline = test::MakeTimeline(o);
  const RunResult result = RunAssembler(timeline, OptionsFor(timeline, o.cameras));
  ASSERT_EQ(result.sets.size(), 400u);
  for (const FrameSet& set : result.sets) EXPECT_TRUE(set.complete()) << set.trigger_index;
  EXPECT_EQ(result.drops.lost(), 0u) << result.drops.OneLine();
  EXPECT_EQ(result.drops.anomalies(), 0u) << result.drops.OneLine();
  EXPECT_EQ(result.drops.OneLine(), "no drops");
  for (const CameraSyncStats& stats : result.stats) {
    EXPECT_EQ(stats.in_sets, 400u);
    EXPECT_EQ(stats.lost_after_exposure + stats.not_exposed + stats.counter_mismatches, 0u);
  }
}

TEST(FrameSetAssembler, CounterSplitsLostFramesFromTriggersNeverExposed) {
  test::TimelineOptions o;
  o.p_failed = o.p_late = o.p_spurious = o.p_vicon_drop = 0.0;
  o.p_lost = 0.05;
  o.p_not_exposed = 0.05;
  o.cameras = 2;
  o.seed = 99;
  const test::Timeline timeline = test::MakeTimeline(o);
  const RunResult result = RunAssembler(timeline, OptionsFor(timeline, o.cameras));
  CheckAgainstTruth(o, timeline, result);
  for (int c = 0; c < o.cameras; ++c) {
    std::uint64_t lost = 0, not_exposed = 0;
    for (int k = 0; k < o.triggers; ++k) {
      lost += timeline.truth[c][k] == Truth::kLost;
      not_exposed += timeline.truth[c][k] == Truth::kNotExposed;
    }
    EXPECT_GT(lost + not_exposed, 0u);
    EXPECT_EQ(result.stats[c].lost_after_exposure, lost) << "camera " << c;
    EXPECT_EQ(result.stats[c].not_exposed, not_exposed) << "camera " << c;
    EXPECT_EQ(result.stats[c].counter_mismatches, 0u);
  }
}

TEST(FrameSetAssembler, ViconStreamStoppingLeavesFramesInSetsMarkedWithoutPoses) {
  test::TimelineOptions o;
  o.p_not_exposed = o.p_lost = o.p_failed = o.p_late = o.p_spurious = o.p_vicon_drop = 0.0;
  o.triggers = 100;
  test::Timeline timeline = test::MakeTimeline(o);
  // The Vicon sender stops after trigger 49's frame.
  const std::int64_t stop_frame = o.f0 + 8 * 49;
  std::erase_if(timeline.events, [&](const test::Event& e) {
    return e.is_vicon && e.vicon.vicon_frame > stop_frame;
  });
  const RunResult result = RunAssembler(timeline, OptionsFor(timeline, o.cameras));
  ASSERT_EQ(result.sets.size(), 100u);
  for (const FrameSet& set : result.sets) {
    EXPECT_TRUE(set.missing.empty());
    EXPECT_EQ(set.vicon.has_value(), set.trigger_index <= 49) << set.trigger_index;
  }
  EXPECT_EQ(result.drops[DropKind::kViconMissingForTrigger], 50u);
  EXPECT_EQ(result.drops[DropKind::kCameraMissedTrigger], 0u);
}

TEST(FrameSetAssembler, KnownF0AndNoViconExpected) {
  test::TimelineOptions o;
  o.p_not_exposed = o.p_lost = o.p_failed = o.p_late = o.p_spurious = 0.0;
  o.p_vicon_drop = 0.0;
  o.triggers = 50;
  const test::Timeline timeline = test::MakeTimeline(o);
  FrameSetAssemblerOptions options = OptionsFor(timeline, o.cameras);
  options.vicon_f0 = o.f0;
  options.vicon_arrival_offset_ns = 0;  // not needed when f0 is given
  const RunResult known = RunAssembler(timeline, options);
  ASSERT_EQ(known.sets.size(), 50u);
  EXPECT_EQ(known.sets[7].vicon_frame, o.f0 + 56);
  EXPECT_TRUE(known.sets[7].complete());

  options.vicon_expected = false;
  const RunResult without = RunAssembler(timeline, options);
  ASSERT_EQ(without.sets.size(), 50u);
  EXPECT_FALSE(without.sets[3].vicon.has_value());
  EXPECT_TRUE(without.sets[3].missing.empty());
  EXPECT_EQ(without.drops.lost(), 0u) << without.drops.OneLine();
}

TEST(FrameSetAssembler, DeviceClockJumpReanchorsTheCamera) {
  test::TimelineOptions o;
  o.p_not_exposed = o.p_lost = o.p_failed = o.p_late = o.p_spurious = o.p_vicon_drop = 0.0;
  o.triggers = 120;
  o.cameras = 2;
  test::Timeline timeline = test::MakeTimeline(o);
  // Camera 1's device clock is reset (e.g. a reconnect) from trigger 60 on.
  for (test::Event& e : timeline.events) {
    if (!e.is_vicon && e.frame.camera_index == 1 && e.host_ns > o.start_host_ns + 60 * o.period_ns)
      e.frame.device_ns -= 123'456'789'000;
  }
  const RunResult result = RunAssembler(timeline, OptionsFor(timeline, o.cameras));
  ASSERT_EQ(result.sets.size(), 120u);
  EXPECT_EQ(result.drops[DropKind::kClockJump], 1u);
  // The frames before the jump is confirmed (jump_confirm = 4 samples) are
  // off the grid by device time: counted as without trigger, never misplaced.
  std::uint64_t in_sets = 0;
  for (const FrameSet& set : result.sets) in_sets += set.frames[1].has_value();
  EXPECT_GE(in_sets, 120u - 4u);
  EXPECT_EQ(in_sets + result.drops[DropKind::kFrameWithoutTrigger], 120u);
  for (int k = 70; k < 120; ++k) EXPECT_TRUE(result.sets[k].complete()) << k;
}

TEST(FrameSetAssembler, OptionsFromTheRigAndTheirChecks) {
  RigConfig rig;
  rig.cameras.resize(2);
  rig.cameras[0].serial = "40398673";
  rig.cameras[1].serial = "40398678";
  rig.vicon.source = ViconSourceKind::kUdp;
  rig.vicon.rate_hz = 100.0;
  rig.vicon.trigger_divider = 10;
  const FrameSetAssemblerOptions options = FrameSetAssemblerOptions::FromRig(rig);
  EXPECT_EQ(options.serials, (std::vector<std::string>{"40398673", "40398678"}));
  EXPECT_EQ(options.trigger.trigger_period_ns, 100'000'000);
  EXPECT_EQ(options.vicon_divider, 10);
  EXPECT_TRUE(options.vicon_expected);
  EXPECT_EQ(options.vicon_phase_tolerance_ns, 5'000'000);
  EXPECT_TRUE(options.Check().ok());
  FrameSetAssemblerOptions bad = options;
  bad.serials.clear();
  EXPECT_FALSE(bad.Check().ok());
  bad = options;
  bad.trigger.tolerance = 0.6;
  EXPECT_FALSE(bad.Check().ok());
  bad = options;
  bad.vicon_divider = 0;
  EXPECT_FALSE(bad.Check().ok());
  // Every message names its field, those of the nested options too.
  auto message = [](const FrameSetAssemblerOptions& o) {
    const Status s = o.Check();
    return s ? std::string("ok") : s.error().message;
  };
  bad = options;
  bad.trigger.tolerance = 0.6;
  EXPECT_NE(message(bad).find("trigger: tolerance"), std::string::npos) << message(bad);
  bad = options;
  bad.trigger.counter_bits = 1;
  EXPECT_NE(message(bad).find("counter_bits"), std::string::npos) << message(bad);
  bad = options;
  bad.clock.jump_confirm = 0;
  EXPECT_NE(message(bad).find("clock model: jump_confirm"), std::string::npos) << message(bad);
  bad = options;
  bad.vicon_rate_hz = std::nan("");
  EXPECT_NE(message(bad).find("vicon_rate_hz"), std::string::npos) << message(bad);
  bad = options;
  bad.max_vicon_frames = 4;
  EXPECT_NE(message(bad).find("max_vicon_frames"), std::string::npos) << message(bad);
}

}  // namespace
}  // namespace lifmcr
