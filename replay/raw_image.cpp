#include "replay/raw_image.h"

#include "config/input_file.h"
#include "config/text_escape.h"
#include "replay/file_descriptor.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <unistd.h>

namespace lifmcr {
namespace {

enum class Container { kBmp, kPng, kTiff, kUnknown };

// pread of up to `size` bytes at `offset`; the count read (0 on error).
std::size_t ReadAt(int fd, void* out, std::size_t size, std::uint64_t offset) {
  ssize_t got = 0;
  while ((got = ::pread(fd, out, size, static_cast<off_t>(offset))) < 0 && errno == EINTR) {
  }
  return got > 0 ? static_cast<std::size_t>(got) : 0;
}

// The size a header declares, against the BMP limits (the same frames).
Status CheckDeclaredSize(const std::filesystem::path& path, const char* container,
                         std::uint64_t width, std::uint64_t height) {
  if (width > static_cast<std::uint64_t>(kBmpLimits.max_side_px) ||
      height > static_cast<std::uint64_t>(kBmpLimits.max_side_px) ||
      width * height > kBmpLimits.max_pixels) {
    return Error{EscapeText(path.string()) + ": " + container + " of " + std::to_string(width) +
                 "x" + std::to_string(height) + " px, expected at most " +
                 std::to_string(kBmpLimits.max_side_px) + " px a side and " +
                 std::to_string(kBmpLimits.max_pixels / 1000000) + " megapixels"};
  }
  return Status::Ok();
}

// The first image's ImageWidth (tag 256) and ImageLength (257) from a
// classic TIFF's first IFD (TIFF 6.0, section 2: 8-byte header with the
// IFD's offset; the IFD a 2-byte entry count, then 12-byte entries of tag,
// type, count, value; SHORT or LONG values sit in the entry). OpenCV's
// imread decodes that first image only. Read before OpenCV allocates for it.
Status CheckTiffSize(const std::filesystem::path& path, int fd, const unsigned char* header,
                     std::uint64_t file_bytes) {
  const bool little = header[0] == 'I';
  const auto u16 = [little](const unsigned char* b) {
    return little ? std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8
                  : std::uint32_t(b[1]) | std::uint32_t(b[0]) << 8;
  };
  const auto u32 = [little](const unsigned char* b) {
    return little ? std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 |
                        std::uint32_t(b[3]) << 24
                  : std::uint32_t(b[3]) | std::uint32_t(b[2]) << 8 | std::uint32_t(b[1]) << 16 |
                        std::uint32_t(b[0]) << 24;
  };
  const std::string where = EscapeText(path.string()) + ": TIFF ";
  const std::uint64_t ifd = u32(header + 4);
  unsigned char count_bytes[2];
  if (ifd < 8 || ifd + 2 > file_bytes || ReadAt(fd, count_bytes, 2, ifd) != 2) {
    return Error{where + "header points its first image directory at byte " + std::to_string(ifd) +
                 ", outside the file's " + std::to_string(file_bytes) + " bytes"};
  }
  // Real files hold 10-30 entries; tags are sorted, so width and height
  // come early, but every entry of a bounded directory is looked at.
  constexpr std::uint32_t kMaxEntries = 4096;
  const std::uint32_t entries = std::min(u16(count_bytes), kMaxEntries);
  std::vector<unsigned char> table(std::size_t{entries} * 12);
  const std::size_t got = ReadAt(fd, table.data(), table.size(), ifd + 2);
  std::uint64_t width = 0, height = 0;
  for (std::size_t at = 0; at + 12 <= got; at += 12) {
    const unsigned char* entry = table.data() + at;
    const std::uint32_t tag = u16(entry), type = u16(entry + 2), count = u32(entry + 4);
    if ((tag != 256 && tag != 257) || count != 1) continue;
    const std::uint64_t value = type == 3 ? u16(entry + 8) : type == 4 ? u32(entry + 8) : 0;
    (tag == 256 ? width : height) = value;
  }
  if (width == 0 || height == 0) {
    return Error{where + "first image directory (byte " + std::to_string(ifd) +
                 ") has no ImageWidth and ImageLength of one SHORT or LONG each"};
  }
  return CheckDeclaredSize(path, "TIFF", width, height);
}

// The container from the first bytes, read through the safe open of
// config/input_file.h (a FIFO, folder or device is an error, never a hang);
// a PNG's IHDR size and a TIFF's first image size are checked against the
// BMP limits before OpenCV allocates for them.
Expected<Container> Sniff(const std::filesystem::path& path) {
  Expected<InputFile> opened = OpenInputFile(
      path, {"a raw frame (BMP, PNG or TIFF)", kBmpLimits.max_file_bytes});
  if (!opened) return opened.error();
  FileDescriptor fd(opened->fd);
  unsigned char magic[24] = {};
  const std::size_t n = ReadAt(fd.get(), magic, sizeof magic, 0);
  if (n >= 2 && magic[0] == 'B' && magic[1] == 'M') return Container::kBmp;
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (n >= 8 && std::memcmp(magic, kPng, 8) == 0) {
    const auto be32 = [&](int at) {
      return (std::uint64_t{magic[at]} << 24) | (std::uint64_t{magic[at + 1]} << 16) |
             (std::uint64_t{magic[at + 2]} << 8) | std::uint64_t{magic[at + 3]};
    };
    if (n == sizeof magic) {
      const Status size = CheckDeclaredSize(path, "PNG", be32(16), be32(20));
      if (!size.ok()) return size.error();
    }
    return Container::kPng;
  }
  if (n >= 8 &&
      ((magic[0] == 'I' && magic[1] == 'I' && magic[2] == 42 && magic[3] == 0) ||
       (magic[0] == 'M' && magic[1] == 'M' && magic[2] == 0 && magic[3] == 42))) {
    const Status size = CheckTiffSize(path, fd.get(), magic, opened->size_bytes);
    if (!size.ok()) return size.error();
    return Container::kTiff;
  }
  return Container::kUnknown;
}

// The smallest of 10, 12, 14, 16 bits that holds `max_value`.
int SignificantBits(double max_value) {
  for (const int bits : {10, 12, 14})
    if (max_value < (1 << bits)) return bits;
  return 16;
}

}  // namespace

std::string RawImageInfo::Describe() const {
  char buf[160];
  const char* colour = file_channels == 1 ? "grey" : file_channels == 3 ? "colour" : "colour+alpha";
  if (file_bits == 8)
    std::snprintf(buf, sizeof buf, "%s 8-bit %s", container.c_str(), colour);
  else
    std::snprintf(buf, sizeof buf, "%s %d-bit %s, %d significant bits scaled to 8",
                  container.c_str(), file_bits, colour, significant_bits);
  return buf;
}

Expected<OwnedImage> ReadRawImage(const std::filesystem::path& path, RawImageInfo* info) {
  RawImageInfo local;
  RawImageInfo& out_info = info != nullptr ? *info : local;
  const Expected<Container> sniffed = Sniff(path);
  if (!sniffed) return sniffed.error();
  const Container container = *sniffed;
  if (container == Container::kBmp) {
    out_info = RawImageInfo{"BMP", 8, 8, 1};
    Expected<OwnedImage> image = ReadBmp(path);
    if (image && image->format == PixelFormat::kBgr8) out_info.file_channels = 3;
    return image;
  }
  if (container == Container::kUnknown) {
    return Error{EscapeText(path.string()) + ": " +
                 "not a BMP, PNG or TIFF file (expected 'BM', the PNG signature or "
                 "'II*'/'MM*' at the start)"};
  }
  out_info.container = container == Container::kPng ? "PNG" : "TIFF";
  cv::Mat mat;
  try {
    mat = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return Error{EscapeText(path.string()) + ": OpenCV: " + Excerpt(e.what(), 200)};
  }
  if (mat.empty()) return Error{EscapeText(path.string()) + ": " + "OpenCV could not decode the image"};
  const int depth = mat.depth(), channels = mat.channels();
  if (depth != CV_8U && depth != CV_16U)
    return Error{EscapeText(path.string()) + ": " +
                 "samples are neither 8- nor 16-bit unsigned integers (OpenCV depth " +
                 std::to_string(depth) + ")"};
  if (channels != 1 && channels != 3 && channels != 4)
    return Error{EscapeText(path.string()) + ": " + std::to_string(channels) +
                 " channels, expected 1 (grey), 3 or 4 (colour)"};
  out_info.file_bits = depth == CV_8U ? 8 : 16;
  out_info.file_channels = channels;
  out_info.significant_bits = 8;
  double scale = 1.0;
  if (depth == CV_16U) {
    double max_value = 0;
    cv::minMaxLoc(mat.reshape(1), nullptr, &max_value);
    out_info.significant_bits = SignificantBits(max_value);
    scale = 1.0 / (1 << (out_info.significant_bits - 8));
  }
  const PixelFormat format = channels == 1 ? PixelFormat::kMono8 : PixelFormat::kBgr8;
  OwnedImage image = OwnedImage::Allocate(mat.cols, mat.rows, format);
  cv::Mat dst(image.height, image.width, channels == 1 ? CV_8UC1 : CV_8UC3, image.pixels.data(),
              image.StrideBytes());
  // Into the image's own buffer: the drop of alpha and the scale to 8 bits
  // write there directly (convertTo rounds and saturates).
  if (channels == 4) {
    cv::Mat bgr;
    cv::cvtColor(mat, bgr, cv::COLOR_BGRA2BGR);
    mat = bgr;
  }
  mat.convertTo(dst, dst.type(), scale);
  if (dst.data != image.pixels.data())
    return Error{EscapeText(path.string()) + ": " + "internal: conversion reallocated the image"};
  return image;
}

}  // namespace lifmcr
