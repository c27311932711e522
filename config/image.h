#pragma once
// Plain image buffers shared by every layer. An ImageView never owns its
// pixels: frames live in pooled buffers from the driver to the last consumer
// (docs/architecture.md, conventions), and readers write into memory the caller provides.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace lifmcr {

enum class PixelFormat {
  kMono8,  // 8-bit grey (or a Bayer mosaic stored as grey)
  kBgr8,   // 24-bit colour in BMP byte order: blue, green, red
};

int BytesPerPixel(PixelFormat format);
std::string_view ToString(PixelFormat format);  // "Mono8", "BGR8"
std::optional<PixelFormat> ParsePixelFormat(std::string_view name);

struct ImageView {
  std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  std::size_t stride_bytes = 0;  // bytes from one row to the next, >= width * bpp
  PixelFormat format = PixelFormat::kMono8;

  std::uint8_t* Row(int y) const { return data + static_cast<std::size_t>(y) * stride_bytes; }
  std::size_t RowBytes() const { return static_cast<std::size_t>(width) * BytesPerPixel(format); }
};

struct ConstImageView {
  const std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  std::size_t stride_bytes = 0;
  PixelFormat format = PixelFormat::kMono8;

  ConstImageView() = default;
  ConstImageView(const std::uint8_t* d, int w, int h, std::size_t stride, PixelFormat f)
      : data(d), width(w), height(h), stride_bytes(stride), format(f) {}
  ConstImageView(const ImageView& v)  // NOLINT: a mutable view is readable
      : data(v.data),
        width(v.width),
        height(v.height),
        stride_bytes(v.stride_bytes),
        format(v.format) {}
  const std::uint8_t* Row(int y) const { return data + static_cast<std::size_t>(y) * stride_bytes; }
  std::size_t RowBytes() const { return static_cast<std::size_t>(width) * BytesPerPixel(format); }
};

// An image that owns its pixels, rows packed (stride = width * bytes per pixel).
// For white images, tests and tools; frames stay in pooled buffers instead.
struct OwnedImage {
  int width = 0;
  int height = 0;
  PixelFormat format = PixelFormat::kMono8;
  std::vector<std::uint8_t> pixels;

  static OwnedImage Allocate(int width, int height, PixelFormat format);
  std::size_t StrideBytes() const {
    return static_cast<std::size_t>(width) * BytesPerPixel(format);
  }
  ImageView View() { return {pixels.data(), width, height, StrideBytes(), format}; }
  ConstImageView View() const { return {pixels.data(), width, height, StrideBytes(), format}; }
};

}  // namespace lifmcr
