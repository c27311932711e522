#pragma once
// Ground-truth image files of `lifmcr synth` (the OpenCV boundary of the
// generator): float32 TIFF maps (NaN where no surface) and 8-bit PNGs.

#include "config/error.h"
#include "config/image.h"

#include <cstdint>
#include <filesystem>
#include <vector>

namespace lifmcr::synth {

// Whether this OpenCV can write the ground truth's TIFF and PNG files; an error
// says which it cannot. Call it once in the thread that starts parallel writers,
// before them: it also builds OpenCV's codec registry (gt_images.cpp says why).
Status CheckImageWriters();
// One-channel float32 TIFF of width x height values, row-major.
Status WriteFloatTiff(const std::filesystem::path& path, int width, int height,
                      const std::vector<float>& values);
// Reads it back (tests and tools); an error names the file.
Expected<std::vector<float>> ReadFloatTiff(const std::filesystem::path& path, int* width,
                                           int* height);
// An 8-bit image (Mono8 or BGR8) as PNG.
Status WritePng(const std::filesystem::path& path, ConstImageView image);

}  // namespace lifmcr::synth
