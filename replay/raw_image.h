#pragma once
// Raw frames as other tools write them: the LiFMCR BMP (replay/bmp.h, read
// straight into the buffer), and PNG or TIFF (public plenoptic datasets and
// RxLive exports), 8 or 16 bits per sample, grey or colour, through OpenCV's
// imgcodecs. The file's content decides the format, not its name.
//
// Decisions:
// - Processing reads 8-bit samples (config/image.h), so a 16-bit file is
//   scaled to 8 bits: v8 = round(v16 / 2^(b - 8)), with b the significant
//   bits, the smallest of 10, 12, 14, 16 that holds the file's largest value
//   (a 12-bit sensor in a 16-bit container keeps all its range). The scale is
//   reported (RawImageInfo), so a white image and a frame read with different
//   scales can be told apart. The 8-bit image is the one copy the decode makes.
// - Colour becomes BGR8 (alpha dropped); grey stays Mono8. A Bayer mosaic is
//   grey here; replay/bayer.h demosaics it when the camera says so.

#include "config/error.h"
#include "replay/bmp.h"

#include <filesystem>
#include <string>

namespace lifmcr {

struct RawImageInfo {
  std::string container;     // "BMP", "PNG", "TIFF"
  int file_bits = 8;         // bits per sample in the file (8 or 16)
  int significant_bits = 8;  // bits kept before the scale to 8 (== file_bits for 8-bit)
  int file_channels = 1;     // 1, 3 or 4
  // One line, e.g. "PNG 16-bit grey, 12 significant bits scaled to 8".
  std::string Describe() const;
};

// BMP, PNG or TIFF into a freshly allocated Mono8 or BGR8 image. Errors name
// the file and what was found (unknown container, 32-bit float, 2 channels).
Expected<OwnedImage> ReadRawImage(const std::filesystem::path& path, RawImageInfo* info = nullptr);

}  // namespace lifmcr
