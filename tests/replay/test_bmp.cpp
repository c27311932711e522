#include "replay/bmp.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

// A BMP assembled field by field, to check the parser against the format
// rather than against our own writer.
struct BmpBytes {
  std::uint32_t dib_bytes = 40;
  std::int32_t width = 1;
  std::int32_t height = 1;
  std::uint16_t planes = 1;
  std::uint16_t bits = 8;
  std::uint32_t compression = 0;
  std::uint32_t colours_used = 0;
  bool grey_palette = true;
  std::optional<std::uint32_t> declared_size;  // default: the real size
  std::optional<std::uint32_t> pixel_offset;   // default: right after the palette
  std::string magic = "BM";
  std::vector<std::uint8_t> pixels;  // file order, rows already padded

  std::string Build() const {
    const std::size_t entries = bits == 8 ? (colours_used == 0 ? 256 : colours_used) : 0;
    const std::size_t palette_end = 14 + dib_bytes + 4 * entries;
    const std::uint32_t offset = pixel_offset.value_or(static_cast<std::uint32_t>(palette_end));
    std::string out(std::max<std::size_t>(palette_end, offset), '\0');
    auto u16 = [&](std::size_t at, std::uint32_t v) {
      out[at] = static_cast<char>(v & 0xFF);
      out[at + 1] = static_cast<char>((v >> 8) & 0xFF);
    };
    auto u32 = [&](std::size_t at, std::uint32_t v) {
      u16(at, v);
      u16(at + 2, v >> 16);
    };
    out[0] = magic[0];
    out[1] = magic[1];
    u32(10, offset);
    u32(14, dib_bytes);
    u32(18, static_cast<std::uint32_t>(width));
    u32(22, static_cast<std::uint32_t>(height));
    u16(26, planes);
    u16(28, bits);
    u32(30, compression);
    u32(46, colours_used);
    for (std::size_t i = 0; i < entries; ++i) {
      const std::size_t at = 14 + dib_bytes + 4 * i;
      out[at] = static_cast<char>(grey_palette ? i : 255 - i);
      out[at + 1] = static_cast<char>(i);
      out[at + 2] = static_cast<char>(i);
    }
    out.append(pixels.begin(), pixels.end());
    u32(2, declared_size.value_or(static_cast<std::uint32_t>(out.size())));
    return out;
  }
};

std::filesystem::path WriteBytes(const test::TempDir& dir, const std::string& name,
                                 const std::string& bytes) {
  const auto path = dir / name;
  test::WriteFile(path, bytes);
  return path;
}

// Header parsing of bytes that are a bad file; the error must name the file.
Error HeaderError(const test::TempDir& dir, const std::string& bytes) {
  const auto path = WriteBytes(dir, "bad.bmp", bytes);
  Expected<BmpHeader> header = ReadBmpHeader(path);
  EXPECT_FALSE(header.ok());
  if (header.ok()) return Error{""};
  test::ExpectMessageHas(header.error(), {path.string()});
  return header.error();
}

TEST(Bmp, RoundTripOverRandomSizesFormatsOrdersAndStrides) {
  test::TempDir dir;
  std::mt19937 rng(20240611);
  std::uniform_int_distribution<int> size(1, 67);
  std::uniform_int_distribution<int> extra_stride(0, 13);
  std::uniform_int_distribution<int> byte(0, 255);
  constexpr std::uint8_t kSentinel = 0xA5;
  for (int iteration = 0; iteration < 80; ++iteration) {
    const PixelFormat format = iteration % 2 == 0 ? PixelFormat::kMono8 : PixelFormat::kBgr8;
    const bool top_down = (iteration / 2) % 2 == 1;
    const int width = size(rng);
    const int height = size(rng);
    const std::size_t row_bytes = static_cast<std::size_t>(width) * BytesPerPixel(format);
    SCOPED_TRACE(std::to_string(width) + "x" + std::to_string(height) + " " +
                 std::string(ToString(format)) + (top_down ? " top-down" : " bottom-up"));

    const std::size_t src_stride = row_bytes + extra_stride(rng);
    std::vector<std::uint8_t> src(src_stride * height);
    for (auto& value : src) value = static_cast<std::uint8_t>(byte(rng));
    const ConstImageView src_view(src.data(), width, height, src_stride, format);
    const auto path = dir / ("frame_" + std::to_string(iteration) + ".bmp");
    ASSERT_TRUE(WriteBmp(path, src_view, top_down).ok());

    Expected<BmpHeader> header = ReadBmpHeader(path);
    ASSERT_TRUE(header.ok()) << header.error().message;
    const std::size_t file_row_bytes = (row_bytes + 3) / 4 * 4;
    EXPECT_EQ(header->width, width);
    EXPECT_EQ(header->height, height);
    EXPECT_EQ(header->format, format);
    EXPECT_EQ(header->top_down, top_down);
    EXPECT_EQ(header->file_row_bytes, file_row_bytes);
    EXPECT_EQ(header->pixel_offset, format == PixelFormat::kMono8 ? 1078u : 54u);
    EXPECT_EQ(header->file_size, header->pixel_offset + file_row_bytes * height);
    EXPECT_EQ(header->file_size, std::filesystem::file_size(path));
    EXPECT_TRUE(header->palette_is_grey);

    // Into a buffer whose stride differs from the source's and the file's.
    const std::size_t dst_stride = row_bytes + extra_stride(rng);
    std::vector<std::uint8_t> dst(dst_stride * height, kSentinel);
    const ImageView dst_view{dst.data(), width, height, dst_stride, format};
    const Status read = ReadBmpInto(path, *header, dst_view);
    ASSERT_TRUE(read.ok()) << read.error().message;
    for (int y = 0; y < height; ++y) {
      ASSERT_TRUE(std::equal(src_view.Row(y), src_view.Row(y) + row_bytes, dst_view.Row(y)))
          << "row " << y;
      // The one-pread path (top-down, stride = padded file row) may fill the gap with padding.
      if (top_down && dst_stride == file_row_bytes) continue;
      for (std::size_t x = row_bytes; x < dst_stride; ++x) {
        ASSERT_EQ(dst_view.Row(y)[x], kSentinel) << "stride bytes of row " << y << " touched";
      }
    }

    Expected<OwnedImage> owned = ReadBmp(path);
    ASSERT_TRUE(owned.ok()) << owned.error().message;
    for (int y = 0; y < height; ++y) {
      ASSERT_TRUE(std::equal(src_view.Row(y), src_view.Row(y) + row_bytes, owned->View().Row(y)));
    }
  }
}

TEST(Bmp, ManyRowsNeedSeveralPreadvCalls) {
  // 3000 rows with padding are 6000 iovecs, more than IOV_MAX (1024).
  test::TempDir dir;
  for (const PixelFormat format : {PixelFormat::kMono8, PixelFormat::kBgr8}) {
    OwnedImage image = OwnedImage::Allocate(5, 3000, format);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) {
      image.pixels[i] = static_cast<std::uint8_t>(i * 7 + i / 13);
    }
    for (const bool top_down : {false, true}) {
      const auto path = dir / "tall.bmp";
      ASSERT_TRUE(WriteBmp(path, image.View(), top_down).ok());
      Expected<OwnedImage> back = ReadBmp(path);
      ASSERT_TRUE(back.ok()) << back.error().message;
      EXPECT_EQ(back->pixels, image.pixels);
    }
  }
}

TEST(Bmp, SinglePreadPathWhenStrideMatchesTheFileRows) {
  // Width 6 Mono8: file rows are 8 bytes; a dst stride of 8 reads in one go.
  test::TempDir dir;
  OwnedImage image = OwnedImage::Allocate(6, 4, PixelFormat::kMono8);
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    image.pixels[i] = static_cast<std::uint8_t>(i);
  const auto path = dir / "td.bmp";
  ASSERT_TRUE(WriteBmp(path, image.View(), /*top_down=*/true).ok());
  Expected<BmpHeader> header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok());
  // The buffer ends right after the last row's pixels: padding must not be read into it.
  std::vector<std::uint8_t> dst(8 * 3 + 6 + 1, 0xEE);
  ASSERT_TRUE(ReadBmpInto(path, *header, {dst.data(), 6, 4, 8, PixelFormat::kMono8}).ok());
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 6; ++x) EXPECT_EQ(dst[8 * y + x], y * 6 + x);
  }
  EXPECT_EQ(dst.back(), 0xEE);
}

TEST(Bmp, WrittenBytesFollowTheFormat) {
  test::TempDir dir;
  // 3x2 Mono8, bottom-up: rows of 3 bytes padded to 4, grey palette.
  const std::vector<std::uint8_t> mono = {10, 11, 12, 20, 21, 22};
  ASSERT_TRUE(
      WriteBmp(dir / "m.bmp", ConstImageView(mono.data(), 3, 2, 3, PixelFormat::kMono8)).ok());
  const std::string m = test::ReadFile(dir / "m.bmp");
  ASSERT_EQ(m.size(), 1078u + 8u);
  auto u32 = [](const std::string& s, std::size_t at) {
    return static_cast<std::uint32_t>(static_cast<std::uint8_t>(s[at])) |
           static_cast<std::uint32_t>(static_cast<std::uint8_t>(s[at + 1])) << 8 |
           static_cast<std::uint32_t>(static_cast<std::uint8_t>(s[at + 2])) << 16 |
           static_cast<std::uint32_t>(static_cast<std::uint8_t>(s[at + 3])) << 24;
  };
  EXPECT_EQ(m.substr(0, 2), "BM");
  EXPECT_EQ(u32(m, 2), 1086u);
  EXPECT_EQ(u32(m, 10), 1078u);
  EXPECT_EQ(u32(m, 14), 40u);
  EXPECT_EQ(u32(m, 18), 3u);
  EXPECT_EQ(u32(m, 22), 2u);
  EXPECT_EQ(u32(m, 28) & 0xFFFF, 8u);
  EXPECT_EQ(u32(m, 30), 0u);
  EXPECT_EQ(u32(m, 54 + 4 * 200), 0x00C8C8C8u);  // palette entry 200 = (200, 200, 200, 0)
  EXPECT_EQ(m.substr(1078), std::string("\x14\x15\x16\0\x0A\x0B\x0C\0", 8));  // bottom row first

  // 2x1 BGR8, top-down: height -1, a row of 6 bytes padded to 8.
  const std::vector<std::uint8_t> bgr = {1, 2, 3, 4, 5, 6};
  ASSERT_TRUE(WriteBmp(dir / "c.bmp", ConstImageView(bgr.data(), 2, 1, 6, PixelFormat::kBgr8),
                       /*top_down=*/true)
                  .ok());
  const std::string c = test::ReadFile(dir / "c.bmp");
  ASSERT_EQ(c.size(), 54u + 8u);
  EXPECT_EQ(u32(c, 10), 54u);
  EXPECT_EQ(u32(c, 22), 0xFFFFFFFFu);
  EXPECT_EQ(u32(c, 28) & 0xFFFF, 24u);
  EXPECT_EQ(c.substr(54), std::string("\x01\x02\x03\x04\x05\x06\0\0", 8));
}

TEST(Bmp, HandBuiltV5TopDownMono) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.dib_bytes = 124;
  bytes.width = 3;
  bytes.height = -2;
  bytes.pixels = {1, 2, 3, 0, 4, 5, 6, 0};
  const auto path = WriteBytes(dir, "v5.bmp", bytes.Build());
  Expected<BmpHeader> header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_EQ(header->dib_header_bytes, 124);
  EXPECT_EQ(header->width, 3);
  EXPECT_EQ(header->height, 2);
  EXPECT_TRUE(header->top_down);
  EXPECT_EQ(header->format, PixelFormat::kMono8);
  EXPECT_EQ(header->pixel_offset, 14u + 124u + 1024u);
  EXPECT_EQ(header->file_row_bytes, 4u);
  Expected<OwnedImage> image = ReadBmp(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  EXPECT_EQ(image->pixels, (std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6}));
}

TEST(Bmp, HandBuiltV4BottomUpBgrWithGapBeforePixels) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.dib_bytes = 108;
  bytes.bits = 24;
  bytes.width = 1;
  bytes.height = 2;
  bytes.pixel_offset = 14 + 108 + 10;       // a gap (e.g. a profile) before the pixels is allowed
  bytes.pixels = {7, 8, 9, 0, 1, 2, 3, 0};  // bottom row first
  const auto path = WriteBytes(dir, "v4.bmp", bytes.Build());
  Expected<BmpHeader> header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_FALSE(header->top_down);
  EXPECT_EQ(header->format, PixelFormat::kBgr8);
  EXPECT_EQ(header->pixel_offset, 132u);
  Expected<OwnedImage> image = ReadBmp(path);
  ASSERT_TRUE(image.ok()) << image.error().message;
  EXPECT_EQ(image->pixels, (std::vector<std::uint8_t>{1, 2, 3, 7, 8, 9}));
}

TEST(Bmp, NonGreyPaletteIsReportedNotFatal) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.grey_palette = false;
  bytes.width = 4;
  bytes.height = 1;
  bytes.pixels = {0, 100, 200, 255};
  const auto path = WriteBytes(dir, "palette.bmp", bytes.Build());
  Expected<BmpHeader> header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_FALSE(header->palette_is_grey);
  EXPECT_NE(header->Describe().find("non-grey palette"), std::string::npos);
  Expected<OwnedImage> image = ReadBmp(path);
  ASSERT_TRUE(image.ok());
  EXPECT_EQ(image->pixels, bytes.pixels);  // the indices, never the palette colours
}

TEST(Bmp, ShortPaletteFromColoursUsed) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.colours_used = 16;
  bytes.width = 4;
  bytes.height = 1;
  bytes.pixels = {0, 5, 10, 15};
  Expected<BmpHeader> header = ReadBmpHeader(WriteBytes(dir, "p16.bmp", bytes.Build()));
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_EQ(header->pixel_offset, 14u + 40u + 64u);
  EXPECT_TRUE(header->palette_is_grey);
}

TEST(Bmp, RejectsATruncatedFileNamingBothByteCounts) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.width = 5;
  bytes.height = 4;
  bytes.pixels.assign(8 * 3 + 3, 0);  // 4 rows of 8 bytes expected, 27 present
  bytes.declared_size = 0;            // a 0 size field is allowed; the rows decide
  const Error error = HeaderError(dir, bytes.Build());
  test::ExpectMessageHas(error, {"truncated", "expected at least 1110 bytes", "the file has 1105"});
}

TEST(Bmp, RejectsAFileSizeFieldLargerThanTheFile) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.width = 4;
  bytes.height = 1;
  bytes.pixels = {1, 2, 3, 4};
  bytes.declared_size = 5000;
  const Error error = HeaderError(dir, bytes.Build());
  test::ExpectMessageHas(error,
                         {"byte 2 (file size)", "says the file has 5000 bytes, it has 1082"});
}

TEST(Bmp, RejectsADibHeaderLargerThanTheFile) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.dib_bytes = 124;
  std::string built = bytes.Build().substr(0, 14 + 60);
  const Error error = HeaderError(dir, built);
  test::ExpectMessageHas(error, {"truncated", "expected at least 138 bytes", "124-byte DIB header",
                                 "the file has 74"});
}

TEST(Bmp, RejectsTinyAndEmptyFiles) {
  test::TempDir dir;
  test::ExpectMessageHas(HeaderError(dir, ""), {"truncated", "the file has 0"});
  test::ExpectMessageHas(HeaderError(dir, "BM\x10"), {"truncated", "the file has 3"});
}

TEST(Bmp, RejectsWrongMagic) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.magic = "PK";
  bytes.pixels = {0, 0, 0, 0};
  test::ExpectMessageHas(HeaderError(dir, bytes.Build()),
                         {"byte 0 (magic)", "expected 'BM', got 0x50 0x4B"});
}

TEST(Bmp, RejectsCompression) {
  test::TempDir dir;
  BmpBytes bytes;
  bytes.compression = 1;
  bytes.pixels = {0, 0, 0, 0};
  test::ExpectMessageHas(HeaderError(dir, bytes.Build()),
                         {"byte 30 (compression)", "BI_RLE8", "expected 0 (BI_RGB"});
}

TEST(Bmp, RejectsUnsupportedBitDepths) {
  test::TempDir dir;
  for (const int bits : {1, 4, 16, 32}) {
    BmpBytes bytes;
    bytes.bits = static_cast<std::uint16_t>(bits);
    bytes.pixels = {0, 0, 0, 0};
    test::ExpectMessageHas(HeaderError(dir, bytes.Build()),
                           {"byte 28 (bits per pixel)", std::to_string(bits) + "-bit",
                            "expected 8 (grey) or 24 (BGR)"});
  }
}

TEST(Bmp, RejectsZeroWidthAndHeight) {
  test::TempDir dir;
  BmpBytes zero_width;
  zero_width.width = 0;
  test::ExpectMessageHas(HeaderError(dir, zero_width.Build()),
                         {"byte 18 (width)", "got 0, expected 1 .. 32768 px"});
  BmpBytes negative_width;
  negative_width.width = -3;
  test::ExpectMessageHas(HeaderError(dir, negative_width.Build()), {"got -3, expected 1 .. 32768 px"});
  BmpBytes zero_height;
  zero_height.height = 0;
  test::ExpectMessageHas(HeaderError(dir, zero_height.Build()), {"byte 22 (height)", "got 0"});
}

TEST(Bmp, RejectsOtherHeaderFaults) {
  test::TempDir dir;
  BmpBytes os2;
  os2.dib_bytes = 12;
  test::ExpectMessageHas(HeaderError(dir, os2.Build()), {"byte 14 (DIB header size)", "OS/2"});
  BmpBytes odd;
  odd.dib_bytes = 77;
  test::ExpectMessageHas(HeaderError(dir, odd.Build()), {"got 77, expected 40"});
  BmpBytes planes;
  planes.planes = 2;
  planes.pixels = {0, 0, 0, 0};
  test::ExpectMessageHas(HeaderError(dir, planes.Build()), {"byte 26 (planes)", "expected 1"});
  BmpBytes inside;
  inside.pixel_offset = 100;  // inside the 256-entry palette
  inside.pixels = {0, 0, 0, 0};
  test::ExpectMessageHas(HeaderError(dir, inside.Build()),
                         {"byte 10 (pixel offset)", "got 100", "expected >= 1078"});
  BmpBytes too_many_colours;
  too_many_colours.colours_used = 300;
  test::ExpectMessageHas(HeaderError(dir, too_many_colours.Build()),
                         {"byte 46 (colours used)", "at most 256"});
}

TEST(Bmp, MissingFileAndFolderAreErrors) {
  test::TempDir dir;
  Expected<BmpHeader> missing = ReadBmpHeader(dir / "nope.bmp");
  ASSERT_FALSE(missing.ok());
  test::ExpectMessageHas(missing.error(), {(dir / "nope.bmp").string(), "no such file or folder"});
  Expected<BmpHeader> folder = ReadBmpHeader(dir.path());
  ASSERT_FALSE(folder.ok());
  test::ExpectMessageHas(folder.error(), {dir.path().string()});
}

TEST(Bmp, RejectsABufferOfTheWrongSizeOrFormat) {
  test::TempDir dir;
  OwnedImage image = OwnedImage::Allocate(5, 4, PixelFormat::kMono8);
  const auto path = dir / "f.bmp";
  ASSERT_TRUE(WriteBmp(path, image.View()).ok());
  Expected<BmpHeader> header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok());

  std::vector<std::uint8_t> buffer(256);
  const Status small = ReadBmpInto(path, *header, {buffer.data(), 4, 4, 4, PixelFormat::kMono8});
  ASSERT_FALSE(small.ok());
  test::ExpectMessageHas(small.error(), {path.string(), "frame is 5x4 Mono8, buffer is 4x4 Mono8"});

  const Status colour = ReadBmpInto(path, *header, {buffer.data(), 5, 4, 15, PixelFormat::kBgr8});
  ASSERT_FALSE(colour.ok());
  test::ExpectMessageHas(colour.error(), {"frame is 5x4 Mono8, buffer is 5x4 BGR8"});

  const Status stride = ReadBmpInto(path, *header, {buffer.data(), 5, 4, 3, PixelFormat::kMono8});
  ASSERT_FALSE(stride.ok());
  test::ExpectMessageHas(stride.error(), {path.string(), "at least 5 bytes, its stride is 3"});

  const Status null = ReadBmpInto(path, *header, {nullptr, 5, 4, 5, PixelFormat::kMono8});
  ASSERT_FALSE(null.ok());
  test::ExpectMessageHas(null.error(), {"no memory"});
}

TEST(Bmp, FileTruncatedAfterItsHeaderWasRead) {
  test::TempDir dir;
  OwnedImage image = OwnedImage::Allocate(7, 9, PixelFormat::kBgr8);
  const auto path = dir / "shrinking.bmp";
  ASSERT_TRUE(WriteBmp(path, image.View()).ok());
  Expected<BmpHeader> header = ReadBmpHeader(path);
  ASSERT_TRUE(header.ok());
  std::filesystem::resize_file(path, header->file_size - 10);
  const Status read = ReadBmpInto(path, *header, image.View());
  ASSERT_FALSE(read.ok());
  test::ExpectMessageHas(read.error(), {path.string(), "truncated",
                                        "expected at least " + std::to_string(header->file_size),
                                        "the file has " + std::to_string(header->file_size - 10)});
}

TEST(Bmp, WriteErrorsNameThePath) {
  test::TempDir dir;
  OwnedImage image = OwnedImage::Allocate(3, 3, PixelFormat::kMono8);
  const auto no_folder = dir / "no" / "such" / "folder.bmp";
  const Status missing = WriteBmp(no_folder, image.View());
  ASSERT_FALSE(missing.ok());
  test::ExpectMessageHas(missing.error(), {no_folder.string(), "cannot create"});

  const Status empty =
      WriteBmp(dir / "e.bmp", ConstImageView(image.pixels.data(), 0, 3, 3, PixelFormat::kMono8));
  ASSERT_FALSE(empty.ok());
  test::ExpectMessageHas(empty.error(), {"e.bmp", "expected width and height > 0"});
  EXPECT_FALSE(std::filesystem::exists(dir / "e.bmp"));

  const Status narrow =
      WriteBmp(dir / "n.bmp", ConstImageView(image.pixels.data(), 3, 3, 2, PixelFormat::kMono8));
  ASSERT_FALSE(narrow.ok());
  test::ExpectMessageHas(narrow.error(), {"stride >= 3"});
}

TEST(Bmp, RandomlyCorruptedHeadersAreRejectedOrConsistent) {
  // Whatever the bytes, parsing never reads past them, and a header it accepts
  // describes pixels that lie inside the file, so reading them is safe.
  test::TempDir dir;
  std::mt19937 rng(99);
  BmpBytes bytes;
  bytes.width = 5;
  bytes.height = -3;
  bytes.pixels.assign(24, 7);
  const std::string valid = bytes.Build();
  std::uniform_int_distribution<std::size_t> position(0, 70);
  std::uniform_int_distribution<int> value(0, 255);
  std::uniform_int_distribution<int> mutations(1, 4);
  int accepted = 0;
  for (int iteration = 0; iteration < 3000; ++iteration) {
    std::vector<std::uint8_t> data(valid.begin(), valid.end());
    for (int m = mutations(rng); m > 0; --m) {
      data[position(rng)] = static_cast<std::uint8_t>(value(rng));
    }
    if (iteration % 3 == 0)
      data.resize(std::uniform_int_distribution<std::size_t>(0, data.size())(rng));
    Expected<BmpHeader> header = ParseBmpHeader(data, data.size(), "fuzz.bmp");
    if (!header.ok()) {
      EXPECT_EQ(header.error().message.rfind("fuzz.bmp: ", 0), 0u) << header.error().message;
      continue;
    }
    ++accepted;
    ASSERT_LE(header->pixel_offset + header->PixelBytes(), data.size());
    if (accepted % 20 == 0) {
      const auto path = WriteBytes(dir, "fuzz.bmp", std::string(data.begin(), data.end()));
      Expected<OwnedImage> image = ReadBmp(path);
      EXPECT_TRUE(image.ok()) << image.error().message;
    }
  }
  EXPECT_GT(accepted, 0);
}

TEST(Bmp, ParseBmpHeaderWorksOnBytesWithoutAFile) {
  BmpBytes bytes;
  bytes.width = 2;
  bytes.height = -1;
  bytes.bits = 24;
  bytes.pixels = {1, 2, 3, 4, 5, 6, 0, 0};
  const std::string built = bytes.Build();
  const std::vector<std::uint8_t> data(built.begin(), built.end());
  Expected<BmpHeader> header = ParseBmpHeader(data, data.size(), "memory");
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_EQ(header->Describe(), "2x1 BGR8 top-down, rows of 8 bytes at offset 54");
  Expected<BmpHeader> short_file = ParseBmpHeader(data, data.size() - 1, "memory");
  ASSERT_FALSE(short_file.ok());
  test::ExpectMessageHas(short_file.error(), {"memory: ", "truncated"});
}

}  // namespace
}  // namespace lifmcr
