#include "replay/mla_xml.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

constexpr char kR42[] = "raytrix_mla_R42_sc2_klein.xml";
constexpr char kR29[] = "raytrix_mla_R29_Cards2_Processed.xml";
constexpr char kFrog[] = "raytrix_mla_frog1_tree_Calibration_rot90.xml";

// Parses `text` as "bad.xml", expects failure and every fragment in the message.
void ExpectError(const std::string& text, const std::vector<std::string>& fragments) {
  const Expected<MlaCalibration> result = ParseMlaXml(text, "bad.xml");
  ASSERT_FALSE(result.ok()) << "expected an error containing " << fragments.front();
  test::ExpectMessageHas(result.error(), fragments);
}

// ------------------------------------------------------------ real samples

TEST(MlaXml, ReadsR42) {
  const Expected<MlaCalibration> mla = ReadMlaXml(test::SamplePath(kR42));
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  EXPECT_EQ(mla->version, "1.0");
  EXPECT_DOUBLE_EQ(mla->offset_px.x(), 17.759811322506);
  EXPECT_DOUBLE_EQ(mla->offset_px.y(), 14.905208990217);
  EXPECT_DOUBLE_EQ(mla->diameter_px, 34.864704132080);
  EXPECT_EQ(mla->rotation_rad, 0.0);
  EXPECT_EQ(mla->lens_border_px, 1.0);
  EXPECT_DOUBLE_EQ(mla->tcp_virtual_depth, 2.180962562561);
  EXPECT_EQ(mla->lens_base_x, Eigen::Vector2d(1.0, 0.0));
  EXPECT_DOUBLE_EQ(mla->lens_base_y.x(), 0.5);
  EXPECT_DOUBLE_EQ(mla->lens_base_y.y(), -0.866025388241);  // negative in this file
  EXPECT_DOUBLE_EQ(mla->sub_grid_base.x(), 3.0);
  EXPECT_DOUBLE_EQ(mla->sub_grid_base.y(), -1.732050776482);
  EXPECT_EQ(mla->distortion.type, "radial");
  EXPECT_EQ(mla->distortion.function, "constant");
  EXPECT_TRUE(mla->distortion.parameters.empty());
  EXPECT_EQ(mla->distortion.offset_px, Eigen::Vector2d::Zero());
  for (int id = 0; id < 3; ++id) EXPECT_EQ(mla->lens_types[id].id, id);
  EXPECT_EQ(mla->lens_types[0].offset_lens, Eigen::Vector2d(0.0, 0.0));
  EXPECT_EQ(mla->lens_types[1].offset_lens, Eigen::Vector2d(1.0, 0.0));
  EXPECT_EQ(mla->lens_types[2].offset_lens, Eigen::Vector2d(-1.0, 0.0));
  EXPECT_EQ(mla->lens_types[0].depth_min, 1.0);
  EXPECT_EQ(mla->lens_types[0].depth_max, 3.0);
  EXPECT_DOUBLE_EQ(mla->lens_types[1].depth_min, 2.799999952316);
  EXPECT_EQ(mla->lens_types[1].depth_max, 4.0);
  EXPECT_DOUBLE_EQ(mla->lens_types[2].depth_min, 3.799999952316);
  EXPECT_EQ(mla->lens_types[2].depth_max, 100.0);
}

TEST(MlaXml, ReadsR29WithBrownDistortionTabsLfAndDeclaration) {
  const std::string text = test::ReadSample(kR29);
  ASSERT_EQ(text.rfind("<?xml", 0), 0u);
  ASSERT_EQ(text.find('\r'), std::string::npos);
  ASSERT_NE(text.find('\t'), std::string::npos);
  const Expected<MlaCalibration> mla = ParseMlaXml(text, kR29);
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  EXPECT_DOUBLE_EQ(mla->offset_px.x(), 22.0742185007);
  EXPECT_DOUBLE_EQ(mla->offset_px.y(), 8.62280279398);
  EXPECT_DOUBLE_EQ(mla->diameter_px, 38.3737792969);
  EXPECT_DOUBLE_EQ(mla->rotation_rad, 2.54233651836e-005);
  EXPECT_EQ(mla->lens_border_px, 1.0);
  EXPECT_DOUBLE_EQ(mla->tcp_virtual_depth, 2.11002731323);
  EXPECT_EQ(mla->lens_base_x.x(), -1.0);  // negative in this file
  EXPECT_DOUBLE_EQ(mla->lens_base_x.y(), -8.74227765735e-008);
  EXPECT_DOUBLE_EQ(mla->lens_base_y.x(), -0.499999910593);
  EXPECT_DOUBLE_EQ(mla->lens_base_y.y(), -0.866025447845);
  EXPECT_DOUBLE_EQ(mla->sub_grid_base.x(), -2.99999976158);
  EXPECT_DOUBLE_EQ(mla->sub_grid_base.y(), -1.7320510149);
  EXPECT_EQ(mla->distortion.function, "Brown");
  ASSERT_EQ(mla->distortion.parameters.size(), 2u);
  EXPECT_DOUBLE_EQ(mla->distortion.parameters[0], -0.00145956683518);
  EXPECT_DOUBLE_EQ(mla->distortion.parameters[1], 0.000735560442194);
  EXPECT_DOUBLE_EQ(mla->distortion.offset_px.x(), 3186.70925279);
  EXPECT_DOUBLE_EQ(mla->distortion.offset_px.y(), 2651.12256994);
  // Mirrored against R42: id 1 sits at -x, id 2 at +x.
  EXPECT_EQ(mla->lens_types[1].offset_lens.x(), -1.0);
  EXPECT_EQ(mla->lens_types[2].offset_lens.x(), 1.0);
  EXPECT_DOUBLE_EQ(mla->lens_types[2].offset_lens.y(), 8.74227765735e-008);
  EXPECT_DOUBLE_EQ(mla->lens_types[1].depth_min, 2.79999995232);
}

TEST(MlaXml, ReadsFrogRotatedNinetyDegreesWithTransposedBases) {
  const Expected<MlaCalibration> mla = ReadMlaXml(test::SamplePath(kFrog));
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  EXPECT_DOUBLE_EQ(mla->rotation_rad, 1.570796370506);
  EXPECT_NEAR(mla->rotation_rad, std::numbers::pi / 2, 1e-6);
  EXPECT_DOUBLE_EQ(mla->offset_px.x(), 13.100938434498);
  EXPECT_DOUBLE_EQ(mla->offset_px.y(), -20.346443871728);
  EXPECT_DOUBLE_EQ(mla->diameter_px, 23.213624954224);
  EXPECT_DOUBLE_EQ(mla->tcp_virtual_depth, 2.207478046417);
  EXPECT_DOUBLE_EQ(mla->lens_base_x.x(), -0.000000043711);
  EXPECT_EQ(mla->lens_base_x.y(), 1.0);
  EXPECT_DOUBLE_EQ(mla->lens_base_y.x(), 0.866025388241);
  EXPECT_DOUBLE_EQ(mla->lens_base_y.y(), 0.500000059605);
  EXPECT_DOUBLE_EQ(mla->sub_grid_base.x(), 1.732050657272);
  EXPECT_EQ(mla->sub_grid_base.y(), 3.0);
  EXPECT_EQ(mla->lens_types[1].offset_lens.y(), 1.0);
  EXPECT_EQ(mla->lens_types[2].offset_lens.y(), -1.0);
  EXPECT_DOUBLE_EQ(mla->lens_types[0].depth_max, 3.200000047684);
  EXPECT_DOUBLE_EQ(mla->lens_types[1].depth_min, 2.599999904633);
  EXPECT_DOUBLE_EQ(mla->lens_types[1].depth_max, 4.199999809265);
  EXPECT_EQ(mla->lens_types[2].depth_min, 3.5);
}

TEST(MlaXml, FormatReproducesRxLiveFilesByteForByte) {
  for (const char* name : {kR42, kFrog}) {
    const std::string text = test::ReadSample(name);
    const Expected<MlaCalibration> mla = ParseMlaXml(text, name);
    ASSERT_TRUE(mla.ok()) << mla.error().message;
    EXPECT_EQ(FormatMlaXml(*mla), text) << name;
  }
}

TEST(MlaXml, MissingFileNamesThePath) {
  const Expected<MlaCalibration> mla = ReadMlaXml("/nonexistent/TypeE_40398673_MLA.xml");
  ASSERT_FALSE(mla.ok());
  EXPECT_NE(mla.error().message.find("/nonexistent/TypeE_40398673_MLA.xml"), std::string::npos);
}

TEST(MlaXml, MissingDistortionMeansConstant) {
  std::string text = test::ReadSample(kR42);
  const size_t begin = text.find("  <distortion");
  const size_t end = text.find("</distortion>\r\n") + std::string("</distortion>\r\n").size();
  text.erase(begin, end - begin);
  const Expected<MlaCalibration> mla = ParseMlaXml(text, "no_distortion.xml");
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  EXPECT_EQ(mla->distortion.function, "constant");
  EXPECT_TRUE(mla->distortion.parameters.empty());
}

TEST(MlaXml, LensTypesInAnyOrderAreStoredAtTheirId) {
  std::string text = test::ReadSample(kR42);
  text = test::ReplaceFirst(text, "<lens_type id=\"0\">", "<lens_type id=\"X\">");
  text = test::ReplaceFirst(text, "<lens_type id=\"2\">", "<lens_type id=\"0\">");
  text = test::ReplaceFirst(text, "<lens_type id=\"X\">", "<lens_type id=\"2\">");
  const Expected<MlaCalibration> mla = ParseMlaXml(text, "swapped.xml");
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  EXPECT_EQ(mla->lens_types[0].offset_lens, Eigen::Vector2d(-1.0, 0.0));
  EXPECT_EQ(mla->lens_types[0].depth_max, 100.0);
  EXPECT_EQ(mla->lens_types[2].offset_lens, Eigen::Vector2d(0.0, 0.0));
  EXPECT_EQ(mla->lens_types[2].id, 2);
}

// ------------------------------------------------------------ round trips

void ExpectNearRelative(double expected, double actual, const std::string& what) {
  EXPECT_LE(std::abs(expected - actual), 1e-12 * std::abs(expected))
      << what << ": " << expected << " vs " << actual;
}

void ExpectSameCalibration(const MlaCalibration& a, const MlaCalibration& b) {
  EXPECT_EQ(a.version, b.version);
  for (int i = 0; i < 2; ++i) {
    ExpectNearRelative(a.offset_px[i], b.offset_px[i], "offset");
    ExpectNearRelative(a.lens_base_x[i], b.lens_base_x[i], "lens_base_x");
    ExpectNearRelative(a.lens_base_y[i], b.lens_base_y[i], "lens_base_y");
    ExpectNearRelative(a.sub_grid_base[i], b.sub_grid_base[i], "sub_grid_base");
    ExpectNearRelative(a.distortion.offset_px[i], b.distortion.offset_px[i], "distortion offset");
  }
  ExpectNearRelative(a.diameter_px, b.diameter_px, "diameter");
  ExpectNearRelative(a.rotation_rad, b.rotation_rad, "rotation");
  ExpectNearRelative(a.lens_border_px, b.lens_border_px, "lens_border");
  ExpectNearRelative(a.tcp_virtual_depth, b.tcp_virtual_depth, "tcp");
  EXPECT_EQ(a.distortion.type, b.distortion.type);
  EXPECT_EQ(a.distortion.function, b.distortion.function);
  ASSERT_EQ(a.distortion.parameters.size(), b.distortion.parameters.size());
  for (size_t i = 0; i < a.distortion.parameters.size(); ++i) {
    ExpectNearRelative(a.distortion.parameters[i], b.distortion.parameters[i], "parameter");
  }
  for (int id = 0; id < 3; ++id) {
    EXPECT_EQ(a.lens_types[id].id, b.lens_types[id].id);
    for (int i = 0; i < 2; ++i) {
      ExpectNearRelative(a.lens_types[id].offset_lens[i], b.lens_types[id].offset_lens[i],
                         "lens type offset");
    }
    ExpectNearRelative(a.lens_types[id].depth_min, b.lens_types[id].depth_min, "depth min");
    ExpectNearRelative(a.lens_types[id].depth_max, b.lens_types[id].depth_max, "depth max");
  }
}

Eigen::Vector2d Rotated(const Eigen::Vector2d& v, double angle_rad) {
  return Eigen::Vector2d(std::cos(angle_rad) * v.x() - std::sin(angle_rad) * v.y(),
                         std::sin(angle_rad) * v.x() + std::cos(angle_rad) * v.y());
}

// A valid hexagonal calibration with random values, signs, mirroring and
// distortion; `rotation_rad` sets the grid direction.
MlaCalibration RandomCalibration(std::mt19937& rng, double rotation_rad) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  auto sign = [&] { return unit(rng) < 0.5 ? -1.0 : 1.0; };
  MlaCalibration c;
  c.offset_px = {uniform(-60, 60), uniform(-60, 60)};
  c.diameter_px = uniform(5, 60);
  c.rotation_rad = rotation_rad;
  c.lens_border_px = uniform(0, 0.49) * c.diameter_px;
  c.tcp_virtual_depth = uniform(1.5, 3);
  c.lens_base_x = sign() * Eigen::Vector2d(std::cos(rotation_rad), std::sin(rotation_rad));
  const double between = (unit(rng) < 0.5 ? 60.0 : 120.0) * sign() * std::numbers::pi / 180.0;
  c.lens_base_y = Rotated(c.lens_base_x, between);
  c.sub_grid_base = {uniform(-4, 4), uniform(-4, 4)};
  if (unit(rng) < 0.5) {
    c.distortion.function = "Brown";
    const int count = 1 + static_cast<int>(rng() % 5);
    for (int i = 0; i < count; ++i) {
      c.distortion.parameters.push_back(sign() * std::pow(10.0, uniform(-9, -1)));
    }
    c.distortion.offset_px = {uniform(0, 6000), uniform(0, 6000)};
  }
  const double mirror = sign();  // which type sits at +lens_base_x varies between files
  for (int id = 0; id < 3; ++id) {
    c.lens_types[id].id = id;
    c.lens_types[id].depth_min = uniform(0.5, 4);
    c.lens_types[id].depth_max = c.lens_types[id].depth_min + uniform(0, 100);
  }
  c.lens_types[1].offset_lens = mirror * c.lens_base_x;
  c.lens_types[2].offset_lens = -mirror * c.lens_base_x;
  return c;
}

TEST(MlaXml, RoundTripOfRandomCalibrations) {
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  test::TempDir dir;
  for (int trial = 0; trial < 200; ++trial) {
    const double rotation = trial % 4 == 0   ? std::numbers::pi / 2
                            : trial % 4 == 1 ? 0.0
                            : trial % 4 == 2 ? angle(rng) * 1e-3
                                             : angle(rng);
    const MlaCalibration original = RandomCalibration(rng, rotation);
    const auto path = dir / ("mla_" + std::to_string(trial) + ".xml");
    const Status written = WriteMlaXml(path, original);
    ASSERT_TRUE(written.ok()) << written.error().message;
    const Expected<MlaCalibration> back = ReadMlaXml(path);
    ASSERT_TRUE(back.ok()) << back.error().message << "\n" << test::ReadFile(path);
    SCOPED_TRACE("trial " + std::to_string(trial));
    ExpectSameCalibration(original, *back);
  }
}

TEST(MlaXml, WriterUsesRxLiveStyle) {
  std::mt19937 rng(7);
  MlaCalibration c = RandomCalibration(rng, std::numbers::pi / 2);
  c.distortion.function = "Brown";
  c.distortion.parameters = {-0.00145956683518, 0.000735560442194};
  const std::string text = FormatMlaXml(c);
  EXPECT_EQ(text.rfind("<RayCalibData version=\"1.0\">\r\n  <offset units=\"pix\">\r\n    <x>", 0),
            0u);
  EXPECT_EQ(text.find("<?xml"), std::string::npos);
  for (size_t i = text.find('\n'); i != std::string::npos; i = text.find('\n', i + 1)) {
    ASSERT_EQ(text[i - 1], '\r') << "bare LF at byte " << i;
  }
  EXPECT_NE(text.find("<parameter count=\"2\">-0.00145956683518;0.000735560442194</parameter>"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("<rotation units=\"rad\">1.570796326795</rotation>"), std::string::npos)
      << "pi/2 in 12 decimals is 1.3e-13 relative off, within 1e-12, so fixed form\n"
      << text;
}

TEST(MlaXml, WriterRefusesAnInvalidCalibration) {
  MlaCalibration c;
  c.diameter_px = -1.0;
  test::TempDir dir;
  const Status status = WriteMlaXml(dir / "out.xml", c);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("/RayCalibData/diameter"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "out.xml"));
  const Status check = CheckMlaCalibration(c);
  ASSERT_FALSE(check.ok());
  EXPECT_NE(check.error().message.find("expected 5 .. 500 px, got -1"), std::string::npos);
}

// ------------------------------------------------------------ bad input

TEST(MlaXmlBadInput, TruncatedFileNamesFileAndLine) {
  const std::string text = test::ReadSample(kR42);
  ExpectError(text.substr(0, text.size() / 2), {"bad.xml:", "malformed XML"});
  const Expected<MlaCalibration> half = ParseMlaXml(text.substr(0, text.size() / 2), "bad.xml");
  ASSERT_FALSE(half.ok());
  EXPECT_EQ(half.error().message.rfind("bad.xml:", 0), 0u);
  EXPECT_TRUE(std::isdigit(static_cast<unsigned char>(half.error().message[8])))
      << half.error().message;
  // Every prefix fails cleanly, none crashes.
  for (size_t size = 0; size < text.size(); size += 3) {
    EXPECT_FALSE(ParseMlaXml(text.substr(0, size), "bad.xml").ok()) << size;
  }
}

TEST(MlaXmlBadInput, WrongRootSuggestsConversion) {
  std::string text = test::ReadSample(kR42);
  text = test::ReplaceFirst(text, "<RayCalibData version=\"1.0\">",
                            "<MlaCalibration version=\"2.0\">");
  text = test::ReplaceFirst(text, "</RayCalibData>", "</MlaCalibration>");
  ExpectError(text, {"bad.xml:1:", "root element is <MlaCalibration>",
                     "RayCalibData version=\"1.0\"", "newer RxLive export", "convert"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "version=\"1.0\"", "version=\"2.0\""),
              {"bad.xml:1:", "/RayCalibData", "version is \"2.0\"", "RayCalibData 1.0"});
}

TEST(MlaXmlBadInput, MissingYOfLensBaseY) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "    <y>-0.866025388241</y>\r\n", ""),
              {"bad.xml:14:", "missing element /RayCalibData/lens_base_y/y"});
}

TEST(MlaXmlBadInput, MissingElementAndDuplicateElement) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42),
                                 "  <tcp units=\"virtual_depth\">2.180962562561</tcp>\r\n", ""),
              {"bad.xml:1:", "missing element /RayCalibData/tcp"});
  ExpectError(test::ReplaceFirst(
                  test::ReadSample(kR42), "<tcp units=\"virtual_depth\">2.180962562561</tcp>\r\n",
                  "<tcp units=\"virtual_depth\">2.18</tcp>\r\n<tcp units=\"virtual_depth\">2."
                  "19</tcp>\r\n"),
              {"bad.xml:10:", "duplicate element <tcp> (first at line 9)"});
}

TEST(MlaXmlBadInput, WrongOrMissingUnits) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<diameter units=\"pix\">",
                                 "<diameter units=\"mm\">"),
              {"bad.xml:6:", "element /RayCalibData/diameter has units 'mm', expected 'pix'"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<lens_base_x units=\"lens\">", "<lens_base_x>"),
      {"bad.xml:10:", "/RayCalibData/lens_base_x has no units attribute",
       "expected units=\"lens\""});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<depth_range units=\"virtual_depth\">",
                                 "<depth_range units=\"pix\">"),
              {"bad.xml:35:", "/RayCalibData/lens_type[@id='0']/depth_range has units 'pix'"});
}

TEST(MlaXmlBadInput, NonNumericValue) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "2.180962562561", "2.18abc"),
              {"bad.xml:9:", "/RayCalibData/tcp", "expected a number, got '2.18abc'"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<x>17.759811322506</x>",
                                 "<x>17,759811322506</x>"),
              {"bad.xml:3:", "/RayCalibData/offset/x", "expected a number"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<x>17.759811322506</x>", "<x></x>"),
              {"bad.xml:3:", "/RayCalibData/offset/x", "expected a number, got ''"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<max>100.000000000000</max>", "<max>inf</max>"),
      {"bad.xml:57:", "/RayCalibData/lens_type[@id='2']/depth_range/max"});
}

TEST(MlaXmlBadInput, TwoLensTypes) {
  std::string text = test::ReadSample(kR42);
  const size_t begin = text.find("  <lens_type id=\"2\">");
  const size_t end = text.find("</lens_type>", begin) + std::string("</lens_type>\r\n").size();
  text.erase(begin, end - begin);
  ExpectError(text, {"bad.xml:1:", "/RayCalibData",
                     "expected exactly three <lens_type> elements (ids 0, 1, 2), found 2"});
}

TEST(MlaXmlBadInput, DuplicateOrOutOfRangeLensTypeId) {
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<lens_type id=\"2\">", "<lens_type id=\"1\">"),
      {"bad.xml:50:", "duplicate lens_type id 1 (first at line 40)"});
  ExpectError(test::ReplaceFirst(test::ReplaceFirst(test::ReadSample(kR42), "<lens_type id=\"1\">",
                                                    "<lens_type id=\"01\">"),
                                 "<min>2.799999952316</min>", "<min>5</min>"),
              {"bad.xml:", "/RayCalibData/lens_type[@id='1']/depth_range", "min < max"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<lens_type id=\"2\">", "<lens_type id=\"3\">"),
      {"bad.xml:50:", "expected lens_type id 0, 1 or 2, got \"3\""});
}

TEST(MlaXmlBadInput, ParameterCountMismatch) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kR29), "count=\"2\"", "count=\"3\""),
              {"bad.xml:25:", "/RayCalibData/distortion/parameter",
               "count=\"3\" but the text holds 2 values"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<parameter count=\"0\">0</parameter>",
                                 "<parameter count=\"0\">0.5;1</parameter>"),
              {"bad.xml:24:", "/RayCalibData/distortion/parameter", "count=\"0\""});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR29), "-0.00145956683518;", "-0.00145956683518;;"),
      {"bad.xml:25:", "value 2 is not a number"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<function>constant</function>",
                                 "<function>Zernike</function>"),
              {"bad.xml:23:", "/RayCalibData/distortion/function", "'constant' or 'Brown'"});
}

TEST(MlaXmlBadInput, BasisGeometry) {
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42),
                         "<x>1.000000000000</x>\r\n    <y>0.000000000000</y>\r\n  </lens_base_x>",
                         "<x>1.100000000000</x>\r\n    <y>0.000000000000</y>\r\n  </lens_base_x>"),
      {"bad.xml:10:", "/RayCalibData/lens_base_x", "expected a unit vector", "1.1"});
  // A unit lens_base_y 30 degrees from lens_base_x: not a hexagonal grid.
  ExpectError(test::ReplaceFirst(test::ReplaceFirst(test::ReadSample(kR42), "<x>0.500000000000</x>",
                                                    "<x>0.866025388241</x>"),
                                 "<y>-0.866025388241</y>", "<y>-0.5</y>"),
              {"bad.xml:14:", "/RayCalibData/lens_base_y", "60 or 120 degrees", "not hexagonal"});
}

TEST(MlaXmlBadInput, DiameterLensBorderAndDepthRange) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "34.864704132080", "0"),
              {"bad.xml:6:", "/RayCalibData/diameter", "expected 5 .. 500 px, got 0"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "34.864704132080", "-3.5"),
              {"bad.xml:6:", "/RayCalibData/diameter", "got -3.5"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<lens_border units=\"pix\">1.000000000000",
                         "<lens_border units=\"pix\">17.5"),
      {"bad.xml:8:", "/RayCalibData/lens_border", "lens_border < diameter/2"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<min>2.799999952316</min>", "<min>5</min>"),
      {"bad.xml:45:", "/RayCalibData/lens_type[@id='1']/depth_range",
       "expected min < max", "got min 5 > max 4"});
  // An empty range leaves the lens type sharp nowhere: depth estimation would
  // find nothing, and the file, not the depth command, is at fault.
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kR42), "<min>2.799999952316</min>", "<min>4</min>"),
      {"bad.xml:45:", "/RayCalibData/lens_type[@id='1']/depth_range",
       "expected min < max (the virtual depths the lens type is sharp in), got min 4 = max 4"});
}

// XML is UTF-8 unless declared otherwise, and tinyxml2 reads every file as
// UTF-8: a Latin-1 byte anywhere (an element the reader ignores, a comment,
// an attribute) is an error naming its element, line and byte.
TEST(MlaXmlBadInput, TextThatIsNotUtf8) {
  const std::string r42 = test::ReadSample(kR42);
  ExpectError(test::ReplaceFirst(r42, "<function>constant</function>",
                                 "<function>constant</function><note>caf\xE9</note>"),
              {"bad.xml:23:", "/RayCalibData/distortion/note", "text is not UTF-8 (byte 0xE9",
               "caf\\xE9", "expected UTF-8 text"});
  ExpectError(test::ReplaceFirst(r42, "<function>constant</function>",
                                 "<function>constant</function>\r\n<!-- r\xE9sum\xE9 -->"),
              {"bad.xml:24:", "a comment is not UTF-8"});
  ExpectError(test::ReplaceFirst(r42, "<distortion type=\"radial\">",
                                 "<distortion type=\"radi\xE4l\">"),
              {"bad.xml:22:", "attribute type is not UTF-8"});
  // A declared encoding other than UTF-8 is named, with the conversion.
  ExpectError("<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n" +
                  test::ReplaceFirst(r42, "<function>constant</function>",
                                     "<function>constant</function><note>\xE9</note>"),
              {"the declaration names encoding ISO-8859-1", "iconv -f ISO-8859-1 -t UTF-8"});
  // Valid UTF-8 that is not ASCII passes.
  const Expected<MlaCalibration> utf8 = ParseMlaXml(
      test::ReplaceFirst(r42, "<function>constant</function>",
                         "<function>constant</function><note>caf\xC3\xA9 \xE6\x97\xA5</note>"),
      "utf8.xml");
  EXPECT_TRUE(utf8.ok()) << utf8.error().message;
}

// A number too small for a double is finite and rounds to zero, as strtod
// rounds it; only one too large is an error (config/decimal_number.h).
TEST(MlaXml, UnderflowReadsAsZero) {
  const Expected<MlaCalibration> mla =
      ParseMlaXml(test::ReplaceFirst(test::ReadSample(kR42), "<x>17.759811322506</x>", "<x>1e-400</x>"),
                  "tiny.xml");
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  EXPECT_EQ(mla->offset_px.x(), 0.0);
  ExpectError(test::ReplaceFirst(test::ReadSample(kR42), "<x>17.759811322506</x>", "<x>1e400</x>"),
              {"bad.xml:3:", "/RayCalibData/offset/x", "expected a number, got '1e400'"});
}

TEST(MlaXmlBadInput, RandomByteCorruptionNeverCrashes) {
  const std::string text = test::ReadSample(kR42);
  std::mt19937 rng(99);
  const std::string alphabet = "<>/=\"' \r\n\t0123456789.-eE;xyzabc&";
  for (int trial = 0; trial < 2000; ++trial) {
    std::string corrupt = text;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      corrupt[rng() % corrupt.size()] = alphabet[rng() % alphabet.size()];
    }
    const Expected<MlaCalibration> result = ParseMlaXml(corrupt, "corrupt.xml");
    if (!result.ok()) {
      EXPECT_EQ(result.error().message.rfind("corrupt.xml", 0), 0u) << result.error().message;
    }
  }
}

}  // namespace
}  // namespace lifmcr
