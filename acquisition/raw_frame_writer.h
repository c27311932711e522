#pragma once
// Writes one camera frame as a LiFMCR raw BMP without copying its pixels.
//
// File layout: a 4096-byte header block (BITMAPFILEHEADER, BITMAPINFOHEADER
// with a negative height, i.e. top-down rows, the grey palette for 8-bit, then
// zeros), and the pixel rows from byte 4096 on, exactly the rows of the pooled
// buffer. `replay/bmp.h` reads such files like any other BMP (the pixel offset
// field says 4096; top-down is part of the format).
//
// Direct path (O_DIRECT): the pooled buffer is 4096-aligned and its capacity a
// multiple of 4096 (drivers/frame_pool.h), so the rows go to the disk straight
// from it, padded to 4096 bytes, then the header block, then ftruncate cuts the
// padding back to the exact BMP size. Buffered path: the same writes without
// O_DIRECT, used where the file system refuses O_DIRECT (tmpfs) or when the
// recorder is configured so.
//
// Crash safety: the pixels are written first and the header last, so a file
// cut short by a crash (kill -9, power loss) has no valid BMP header or too few
// bytes, and `lifmcr info` reports it as a broken frame instead of serving
// garbage pixels; every file finished before the crash is complete.
//
// A frame whose rows are not laid out as a BMP needs them (stride != the row
// size padded to 4 bytes) is written through a row-by-row staging copy; that
// copy is the only one and happens only for such odd widths.

#include "config/error.h"
#include "drivers/frame.h"

#include <cstddef>
#include <filesystem>

namespace lifmcr {

inline constexpr std::size_t kRawBmpPixelOffset = 4096;

enum class WritePath { kDirect, kBuffered };

struct RawFrameWriteResult {
  WritePath path = WritePath::kBuffered;
  std::size_t file_bytes = 0;  // size of the finished BMP
};

// The 4096-byte header block of a top-down BMP for `width` x `height` of
// `format` with pixels at kRawBmpPixelOffset. `block` must hold 4096 bytes.
void FillRawBmpHeaderBlock(int width, int height, PixelFormat format, std::uint8_t* block);

// The size of the finished file for that image.
std::size_t RawBmpFileBytes(int width, int height, PixelFormat format);

// Writes `frame` to `path` (created or replaced). `try_direct`: use O_DIRECT
// when the file system takes it, else the buffered path. On error the partial
// file is removed and the Error carries errno in `*error_number` (when given)
// so the caller can tell a full disk (ENOSPC, EFBIG) from other failures.
Expected<RawFrameWriteResult> WriteRawFrame(const std::filesystem::path& path, const Frame& frame,
                                            bool try_direct, int* error_number = nullptr);

}  // namespace lifmcr
