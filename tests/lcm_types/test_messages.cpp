// Every lifmcr LCM type encodes and decodes to itself (the generated C++
// code from lcm-gen), and the sizes of variable arrays are honoured.

#include <gtest/gtest.h>

#include <lifmcr_lcm/camera_extrinsics_t.hpp>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/pipeline_stats_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <random>
#include <vector>

namespace {

template <typename Message>
Message RoundTrip(const Message& message) {
  std::vector<std::uint8_t> buffer(message.getEncodedSize());
  EXPECT_EQ(message.encode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  Message decoded;
  EXPECT_EQ(decoded.decode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  // A truncated buffer is refused, never read past.
  Message partial;
  EXPECT_LT(partial.decode(buffer.data(), 0, static_cast<int>(buffer.size()) - 1), 0);
  return decoded;
}

TEST(LcmTypes, PreviewImage) {
  std::mt19937 rng(1);
  lifmcr_lcm::preview_image_t m;
  m.utime = 1700000000123456;
  m.serial = "40398678";
  m.frame_id = 42;
  m.trigger_index = 41;
  m.source_width = 6560;
  m.source_height = 4948;
  m.width = 820;
  m.height = 618;
  m.row_stride = 820;
  m.channels = 1;
  m.encoding = lifmcr_lcm::preview_image_t::ENCODING_RAW;
  m.data.resize(static_cast<std::size_t>(m.row_stride) * m.height);
  for (auto& b : m.data) b = static_cast<std::uint8_t>(rng());
  m.size = static_cast<int32_t>(m.data.size());
  const auto d = RoundTrip(m);
  EXPECT_EQ(d.serial, m.serial);
  EXPECT_EQ(d.frame_id, 42);
  EXPECT_EQ(d.data, m.data);
}

TEST(LcmTypes, DepthImage) {
  lifmcr_lcm::depth_image_t m;
  m.utime = 5;
  m.serial = "40398673";
  m.kind = lifmcr_lcm::depth_image_t::KIND_METRIC_MM;
  m.geometry = lifmcr_lcm::depth_image_t::GEOMETRY_TOTALLY_FOCUSED;
  m.width = 4;
  m.height = 2;
  m.scale = 0.5f;
  m.offset = 100.0f;
  m.valid_fraction = 0.75f;
  m.data = std::vector<std::uint8_t>(16, 7);
  m.size = 16;
  const auto d = RoundTrip(m);
  EXPECT_EQ(d.kind, m.kind);
  EXPECT_FLOAT_EQ(d.scale, 0.5f);
  EXPECT_EQ(d.data, m.data);
}

TEST(LcmTypes, CameraExtrinsics) {
  lifmcr_lcm::camera_extrinsics_t m{};
  m.reference_serial = "40398678";
  m.serial = "40398673";
  m.method = "pnp";
  m.t_mm[0] = 123.5;
  m.q_wxyz[0] = 1.0;
  m.covariance[5][5] = 1e-6;
  m.inliers = 311;
  m.rmse_px = 0.42;
  m.status = "ok";
  const auto d = RoundTrip(m);
  EXPECT_EQ(d.t_mm[0], 123.5);
  EXPECT_EQ(d.covariance[5][5], 1e-6);
  EXPECT_EQ(d.status, "ok");
}

TEST(LcmTypes, ViconFrameWithObjects) {
  lifmcr_lcm::vicon_frame_t m{};
  m.vicon_frame = 801;
  m.is_trigger = true;
  for (const char* name : {"cam0", "cam2", "plate"}) {
    lifmcr_lcm::vicon_object_t o{};
    o.name = name;
    o.occluded = std::string(name) == "cam2";
    o.q_wxyz[0] = 1;
    o.t_mm[2] = 1000;
    m.objects.push_back(o);
  }
  m.num_objects = 3;
  const auto d = RoundTrip(m);
  ASSERT_EQ(d.objects.size(), 3u);
  EXPECT_TRUE(d.objects[1].occluded);
  EXPECT_EQ(d.objects[2].name, "plate");
}

TEST(LcmTypes, PipelineStats) {
  lifmcr_lcm::pipeline_stats_t m{};
  lifmcr_lcm::stage_stats_t s{};
  s.name = "depth";
  s.rate_hz = 9.8;
  s.skipped = 3;
  m.stages = {s, s};
  m.num_stages = 2;
  m.drops = {{"camera_missed_trigger", 2}};
  m.num_drops = 1;
  const auto d = RoundTrip(m);
  EXPECT_EQ(d.stages[1].name, "depth");
  EXPECT_EQ(d.drops[0].kind, "camera_missed_trigger");
  EXPECT_EQ(d.drops[0].count, 2);
}

}  // namespace
