#include "config/image.h"

#include <algorithm>

namespace lifmcr {

int BytesPerPixel(PixelFormat format) { return format == PixelFormat::kBgr8 ? 3 : 1; }

std::string_view ToString(PixelFormat format) {
  return format == PixelFormat::kBgr8 ? "BGR8" : "Mono8";
}

std::optional<PixelFormat> ParsePixelFormat(std::string_view name) {
  if (name == "Mono8") return PixelFormat::kMono8;
  if (name == "BGR8") return PixelFormat::kBgr8;
  return std::nullopt;
}

OwnedImage OwnedImage::Allocate(int width, int height, PixelFormat format) {
  OwnedImage image;
  image.width = width;
  image.height = height;
  image.format = format;
  image.pixels.resize(image.StrideBytes() * static_cast<std::size_t>(std::max(height, 0)));
  return image;
}

}  // namespace lifmcr
