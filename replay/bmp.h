#pragma once
// Raw BMP frames of the LiFMCR layout: 8-bit grey (a Bayer mosaic stored as
// grey, with a palette) or 24-bit BGR, uncompressed. An R32 frame is
// 6560x4948 (32 MB grey, 97 MB colour), so reading goes straight from the
// file into the caller's (pooled) buffer with no intermediate copy.
//
// File layout (all little-endian):
//   0   BITMAPFILEHEADER  'B''M', u32 file size, u32 reserved, u32 pixel offset
//   14  DIB header        u32 size: 40 (BITMAPINFOHEADER), 52/56 (V2/V3),
//                         108 (V4) or 124 (V5); then i32 width, i32 height
//                         (> 0: bottom-up, < 0: top-down), u16 planes = 1,
//                         u16 bits per pixel, u32 compression (0 = BI_RGB),
//                         u32 image size, i32 x/y pixels per metre,
//                         u32 colours used (0 = 2^bits), u32 colours important
//   14 + DIB size         palette of BGRX entries (8-bit only)
//   pixel offset          rows of width * bytes-per-pixel bytes, each padded
//                         with zeros to a multiple of 4 bytes
//
// Decisions:
// - Only 8-bit (palette) and 24-bit BI_RGB are accepted; 1/4/16/32-bit,
//   compressed (RLE, bit fields, JPEG, PNG) and the old 12-byte OS/2 header
//   are errors that say what was found and what is expected.
// - An 8-bit palette is never applied: the pixel values are the sensor values.
//   A palette that is not the identity grey ramp (entry i = (i, i, i)) is not
//   an error; it is reported in `BmpHeader::palette_is_grey` so a tool can warn.
// - The file must hold every row including its padding:
//   pixel_offset + file_row_bytes * height <= file size; otherwise the file is
//   truncated and the error names the expected and the actual byte count. The
//   header's own file-size field (bfSize) may be 0 (allowed by the format) but,
//   when set, must not exceed the real size either.
// - width, height and their product within kBmpLimits.
// - Bytes after the last row (some writers append an ICC profile) are ignored.

#include "config/error.h"
#include "config/image.h"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

// What a real camera frame can be (docs/formats.md, "Limits of every input"): the
// R32 is 6560x4948; the largest industrial sensors have ~150 MP. A header
// beyond is refused before anything is allocated for it.
struct BmpLimits {
  std::int32_t max_side_px = 32768;
  std::uint64_t max_pixels = 268435456;        // 2^28 = 268 MP
  std::uint64_t max_file_bytes = 4ull << 30;  // the format's 32-bit sizes
};
inline constexpr BmpLimits kBmpLimits{};

struct BmpHeader {
  int width = 0;
  int height = 0;  // always > 0; the sign of the file's field is in top_down
  PixelFormat format = PixelFormat::kMono8;
  bool top_down = false;           // false: the first row in the file is the bottom row
  std::size_t file_row_bytes = 0;  // width * bytes per pixel, padded to a multiple of 4
  std::size_t pixel_offset = 0;    // byte offset of the first row in the file
  std::size_t file_size = 0;       // actual size of the file in bytes
  int dib_header_bytes = 0;        // 40, 52, 56, 108 or 124
  bool palette_is_grey = true;     // 8-bit: entry i is (i, i, i); always true for 24-bit

  // Bytes of pixel data (with padding) the file must hold after pixel_offset.
  std::size_t PixelBytes() const { return file_row_bytes * static_cast<std::size_t>(height); }
  // One line, e.g. "6560x4948 Mono8 bottom-up, rows of 6560 bytes at offset 1078".
  std::string Describe() const;
};

// Parses the headers from the first bytes of a file (`prefix`, at most the
// whole file) whose total size is `file_size`; `file_name` is used in errors.
// ReadBmpHeader calls this; it is public so hand-built headers can be checked
// without a file.
Expected<BmpHeader> ParseBmpHeader(std::span<const std::uint8_t> prefix, std::size_t file_size,
                                   const std::string& file_name);

// Reads and validates the headers of `path` (see the decisions above).
Expected<BmpHeader> ReadBmpHeader(const std::filesystem::path& path);

// Reads the pixels of `path`, described by `header` (from ReadBmpHeader), into
// `dst`, whose size and format must match the header and whose stride may be
// larger than a row. Rows land directly in `dst`: one pread when the file is
// top-down and its padded rows have dst's stride, otherwise preadv with one
// iovec per row (in reverse order for bottom-up files) and the row padding
// sent to a small scratch, IOV_MAX iovecs per call. Bytes of dst between the
// end of a row and the next row are left untouched, except in the one-pread
// case, where they receive the file's row padding. An error names the file;
// on error dst may hold part of the frame.
Status ReadBmpInto(const std::filesystem::path& path, const BmpHeader& header, ImageView dst);

// ReadBmpHeader + ReadBmpInto into a freshly allocated image (config/image.h).
Expected<OwnedImage> ReadBmp(const std::filesystem::path& path);

// The BMP file header, BITMAPINFOHEADER and (Mono8) grey palette of a width x
// height image whose pixels start at byte `pixel_offset` of the file (>=
// BmpHeaderBytes(format); a writer may leave a gap, e.g. to align the pixels
// for O_DIRECT). Writes BmpHeaderBytes(format) bytes to `out`. The one place
// that knows the header layout: WriteBmp and the recorder's writer use it.
std::size_t BmpHeaderBytes(PixelFormat format);
void FormatBmpHeader(int width, int height, PixelFormat format, bool top_down,
                     std::size_t pixel_offset, std::uint8_t* out);

// Writes `image` as an uncompressed BMP with a 40-byte BITMAPINFOHEADER:
// Mono8 as 8-bit with the identity grey palette, BGR8 as 24-bit; rows padded
// to 4 bytes; bottom-up (the common form) unless `top_down`. The rows go out
// with pwritev straight from `image` (the padding from a small zero block), so
// no copy of the image is made. On error the partial file is removed.
Status WriteBmp(const std::filesystem::path& path, ConstImageView image, bool top_down = false);

}  // namespace lifmcr
