// Raw frames other tools write: PNG and TIFF at 8 and 16 bits, grey and
// colour, read to the same pixels as the BMP; Bayer mosaics demosaiced to
// the colours they sampled.

#include "replay/bayer.h"
#include "replay/raw_image.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdint>
#include <random>

namespace lifmcr {
namespace {

OwnedImage RandomImage(int w, int h, PixelFormat format, unsigned seed) {
  OwnedImage image = OwnedImage::Allocate(w, h, format);
  std::mt19937 rng(seed);
  for (std::uint8_t& p : image.pixels) p = static_cast<std::uint8_t>(rng() & 0xFF);
  return image;
}

cv::Mat AsMat(const OwnedImage& image) {
  return cv::Mat(image.height, image.width, image.format == PixelFormat::kMono8 ? CV_8UC1 : CV_8UC3,
                 const_cast<std::uint8_t*>(image.pixels.data()), image.StrideBytes());
}

TEST(RawImage, PngTiffAndBmpGiveTheSamePixels) {
  test::TempDir dir;
  for (const PixelFormat format : {PixelFormat::kMono8, PixelFormat::kBgr8}) {
    const OwnedImage truth = RandomImage(37, 21, format, 3);
    const cv::Mat mat = AsMat(truth);
    ASSERT_TRUE(WriteBmp(dir / "a.bmp", truth.View()).ok());
    ASSERT_TRUE(cv::imwrite((dir / "a.png").string(), mat));
    ASSERT_TRUE(cv::imwrite((dir / "a.tiff").string(), mat));
    for (const char* name : {"a.bmp", "a.png", "a.tiff"}) {
      RawImageInfo info;
      Expected<OwnedImage> read = ReadRawImage(dir / name, &info);
      ASSERT_TRUE(read.ok()) << name << ": " << read.error().message;
      EXPECT_EQ(read->format, format) << name;
      EXPECT_EQ(read->pixels, truth.pixels) << name;
      EXPECT_EQ(info.file_bits, 8);
      EXPECT_EQ(info.file_channels, format == PixelFormat::kMono8 ? 1 : 3) << name;
    }
  }
}

TEST(RawImage, SixteenBitsScaleBySignificantBits) {
  test::TempDir dir;
  // A 12-bit sensor in a 16-bit container: 4095 -> 255, 2048 -> 128, 17 -> 1.
  cv::Mat grey(4, 8, CV_16UC1, cv::Scalar(2048));
  grey.at<std::uint16_t>(0, 0) = 4095;
  grey.at<std::uint16_t>(1, 1) = 17;
  for (const char* name : {"g.png", "g.tif"}) {
    ASSERT_TRUE(cv::imwrite((dir / name).string(), grey));
    RawImageInfo info;
    Expected<OwnedImage> read = ReadRawImage(dir / name, &info);
    ASSERT_TRUE(read.ok()) << read.error().message;
    EXPECT_EQ(info.file_bits, 16);
    EXPECT_EQ(info.significant_bits, 12);
    EXPECT_NE(info.Describe().find("12 significant bits"), std::string::npos) << info.Describe();
    EXPECT_EQ(read->format, PixelFormat::kMono8);
    EXPECT_EQ(read->pixels[0], 255);
    EXPECT_EQ(read->pixels[9], 1);
    EXPECT_EQ(read->pixels[2], 128);
  }
  // Full 16-bit colour with alpha: BGR8, alpha dropped.
  cv::Mat bgra(2, 3, CV_16UC4, cv::Scalar(65535, 256, 0, 1000));
  ASSERT_TRUE(cv::imwrite((dir / "c.png").string(), bgra));
  RawImageInfo info;
  Expected<OwnedImage> read = ReadRawImage(dir / "c.png", &info);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(info.significant_bits, 16);
  EXPECT_EQ(info.file_channels, 4);
  ASSERT_EQ(read->format, PixelFormat::kBgr8);
  EXPECT_EQ(read->pixels[0], 255);
  EXPECT_EQ(read->pixels[1], 1);
  EXPECT_EQ(read->pixels[2], 0);
}

TEST(RawImage, ErrorsNameTheFile) {
  test::TempDir dir;
  test::WriteFile(dir / "x.png", "GIF89a not an image");
  Expected<OwnedImage> bad = ReadRawImage(dir / "x.png");
  ASSERT_FALSE(bad.ok());
  test::ExpectMessageHas(bad.error(), {"x.png", "not a BMP, PNG or TIFF"});
  Expected<OwnedImage> missing = ReadRawImage(dir / "none.tiff");
  ASSERT_FALSE(missing.ok());
  test::ExpectMessageHas(missing.error(), {"none.tiff", "no such file"});
  cv::Mat f(3, 3, CV_32FC1, cv::Scalar(0.5));
  ASSERT_TRUE(cv::imwrite((dir / "f.tiff").string(), f));
  Expected<OwnedImage> floats = ReadRawImage(dir / "f.tiff");
  ASSERT_FALSE(floats.ok());
  test::ExpectMessageHas(floats.error(), {"f.tiff", "8- nor 16-bit"});
}

// A classic TIFF header and first directory with only ImageWidth and
// ImageLength (LONG), in either byte order: what a forged or truncated file
// declares before any pixel.
std::string TiffHeader(bool little, std::uint32_t width, std::uint32_t height,
                       std::uint32_t ifd_offset = 8) {
  std::string out;
  const auto put = [&](std::uint32_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) {
      const int shift = little ? 8 * i : 8 * (bytes - 1 - i);
      out += static_cast<char>((v >> shift) & 0xFF);
    }
  };
  out += little ? "II" : "MM";
  put(42, 2);
  put(ifd_offset, 4);
  put(2, 2);  // entries
  put(256, 2), put(4, 2), put(1, 4), put(width, 4);
  put(257, 2), put(4, 2), put(1, 4), put(height, 4);
  put(0, 4);  // no next directory
  return out;
}

TEST(RawImage, DeclaredSizeIsCheckedBeforeDecoding) {
  test::TempDir dir;
  // 30000 x 30000 is within OpenCV's own pixel limit (2^30), so without the
  // check OpenCV would allocate 900 MB for it.
  for (const bool little : {true, false}) {
    const auto path = dir / (little ? "ii.tif" : "mm.tif");
    test::WriteFile(path, TiffHeader(little, 30000, 30000));
    const Expected<OwnedImage> read = ReadRawImage(path);
    ASSERT_FALSE(read.ok());
    test::ExpectMessageHas(read.error(),
                           {path.filename().string(), "TIFF of 30000x30000 px", "268 megapixels"});
  }
  test::WriteFile(dir / "side.tif", TiffHeader(true, 40000, 2));
  test::ExpectMessageHas(ReadRawImage(dir / "side.tif").error(), {"TIFF of 40000x2 px"});
  test::WriteFile(dir / "off.tif", TiffHeader(true, 10, 10, 1u << 30));
  test::ExpectMessageHas(ReadRawImage(dir / "off.tif").error(),
                         {"off.tif", "first image directory at byte 1073741824", "outside"});
  std::string no_size = TiffHeader(true, 10, 10);
  no_size[10] = 0x10;  // the first tag becomes 272 (Model): no ImageWidth
  no_size[11] = 0x01;
  test::WriteFile(dir / "nosize.tif", no_size);
  test::ExpectMessageHas(ReadRawImage(dir / "nosize.tif").error(),
                         {"nosize.tif", "no ImageWidth and ImageLength"});

  // A PNG's IHDR: a real 2x2 PNG with its declared size rewritten.
  ASSERT_TRUE(cv::imwrite((dir / "a.png").string(), cv::Mat(2, 2, CV_8UC1, cv::Scalar(9))));
  std::string png = test::ReadFile(dir / "a.png");
  ASSERT_GE(png.size(), 24u);
  for (const int at : {16, 20}) {
    png[at] = 0, png[at + 1] = 0, png[at + 2] = 0x75, png[at + 3] = 0x30;  // 30000
  }
  test::WriteFile(dir / "big.png", png);
  test::ExpectMessageHas(ReadRawImage(dir / "big.png").error(), {"PNG of 30000x30000 px"});
}

// A flat colour (b, g, r) sampled by each GenICam pattern and demosaiced
// gives that colour back (away from the border).
TEST(Bayer, EachPatternGivesBackTheColourItSampled) {
  const int w = 16, h = 12;
  const std::uint8_t bgr[3] = {30, 120, 210};
  // GenICam: the colours of the first row's first two pixels; the second row
  // holds the other two.
  struct Case {
    CameraPixelFormat format;
    int first_row[2], second_row[2];  // channel index (0 = B, 1 = G, 2 = R)
  };
  for (const Case& c : {Case{CameraPixelFormat::kBayerRg8, {2, 1}, {1, 0}},
                        Case{CameraPixelFormat::kBayerGr8, {1, 2}, {0, 1}},
                        Case{CameraPixelFormat::kBayerGb8, {1, 0}, {2, 1}},
                        Case{CameraPixelFormat::kBayerBg8, {0, 1}, {1, 2}}}) {
    OwnedImage mosaic = OwnedImage::Allocate(w, h, PixelFormat::kMono8);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int* row = y % 2 == 0 ? c.first_row : c.second_row;
        mosaic.pixels[static_cast<std::size_t>(y) * w + x] = bgr[row[x % 2]];
      }
    OwnedImage colour = OwnedImage::Allocate(w, h, PixelFormat::kBgr8);
    ASSERT_TRUE(DemosaicBayer(mosaic.View(), c.format, colour.View()).ok());
    const std::uint8_t* p = colour.pixels.data() + (6 * w + 7) * 3;
    EXPECT_NEAR(p[0], bgr[0], 2) << ToString(c.format);
    EXPECT_NEAR(p[1], bgr[1], 2) << ToString(c.format);
    EXPECT_NEAR(p[2], bgr[2], 2) << ToString(c.format);
  }
  OwnedImage mosaic = OwnedImage::Allocate(w, h, PixelFormat::kMono8);
  OwnedImage colour = OwnedImage::Allocate(w, h, PixelFormat::kBgr8);
  EXPECT_FALSE(DemosaicBayer(mosaic.View(), CameraPixelFormat::kMono8, colour.View()).ok());
}

}  // namespace
}  // namespace lifmcr
