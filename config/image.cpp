#include "config/image.h"

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

}  // namespace lifmcr
