#include "replay/raw_image.h"

#include "config/input_file.h"
#include "config/text_escape.h"
#include "replay/file_descriptor.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <unistd.h>

namespace lifmcr {
namespace {

enum class Container { kBmp, kPng, kTiff, kUnknown };

// The container from the first bytes, read through the safe open of
// config/input_file.h (a FIFO, folder or device is an error, never a hang);
// a PNG's IHDR size is checked against the BMP limits before OpenCV
// allocates for it.
Expected<Container> Sniff(const std::filesystem::path& path) {
  Expected<InputFile> opened = OpenInputFile(
      path, {"a raw frame (BMP, PNG or TIFF)", kBmpLimits.max_file_bytes});
  if (!opened) return opened.error();
  FileDescriptor fd(opened->fd);
  unsigned char magic[24] = {};
  ssize_t got = 0;
  while ((got = ::pread(fd.get(), magic, sizeof magic, 0)) < 0 && errno == EINTR) {
  }
  const std::size_t n = got > 0 ? static_cast<std::size_t>(got) : 0;
  if (n >= 2 && magic[0] == 'B' && magic[1] == 'M') return Container::kBmp;
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (n >= 8 && std::memcmp(magic, kPng, 8) == 0) {
    const auto be32 = [&](int at) {
      return (std::uint64_t{magic[at]} << 24) | (std::uint64_t{magic[at + 1]} << 16) |
             (std::uint64_t{magic[at + 2]} << 8) | std::uint64_t{magic[at + 3]};
    };
    if (n == sizeof magic) {
      const std::uint64_t width = be32(16), height = be32(20);
      if (width > static_cast<std::uint64_t>(kBmpLimits.max_side_px) ||
          height > static_cast<std::uint64_t>(kBmpLimits.max_side_px) ||
          width * height > kBmpLimits.max_pixels) {
        return Error{EscapeText(path.string()) + ": PNG of " + std::to_string(width) + "x" +
                     std::to_string(height) + " px, expected at most " +
                     std::to_string(kBmpLimits.max_side_px) + " px a side and " +
                     std::to_string(kBmpLimits.max_pixels / 1000000) + " megapixels"};
      }
    }
    return Container::kPng;
  }
  if (n >= 4 &&
      ((magic[0] == 'I' && magic[1] == 'I' && magic[2] == 42 && magic[3] == 0) ||
       (magic[0] == 'M' && magic[1] == 'M' && magic[2] == 0 && magic[3] == 42)))
    return Container::kTiff;
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
    return Error{path.string() + ": " +
                 "not a BMP, PNG or TIFF file (expected 'BM', the PNG signature or "
                 "'II*'/'MM*' at the start)"};
  }
  out_info.container = container == Container::kPng ? "PNG" : "TIFF";
  cv::Mat mat;
  try {
    mat = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return Error{path.string() + ": " + std::string("OpenCV: ") + e.what()};
  }
  if (mat.empty()) return Error{path.string() + ": " + "OpenCV could not decode the image"};
  const int depth = mat.depth(), channels = mat.channels();
  if (depth != CV_8U && depth != CV_16U)
    return Error{path.string() + ": " +
                 "samples are neither 8- nor 16-bit unsigned integers (OpenCV depth " +
                 std::to_string(depth) + ")"};
  if (channels != 1 && channels != 3 && channels != 4)
    return Error{path.string() + ": " + std::to_string(channels) +
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
    return Error{path.string() + ": " + "internal: conversion reallocated the image"};
  return image;
}

}  // namespace lifmcr
