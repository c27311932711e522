#include "acquisition/raw_frame_writer.h"

#include "replay/bmp.h"
#include "replay/file_descriptor.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <memory>
#include <sys/stat.h>
#include <unistd.h>

namespace lifmcr {
namespace {

constexpr std::size_t kBlock = 4096;

std::size_t RoundUp(std::size_t bytes) { return (bytes + kBlock - 1) / kBlock * kBlock; }

std::size_t PaddedRowBytes(int width, PixelFormat format) {
  return (static_cast<std::size_t>(width) * BytesPerPixel(format) + 3) / 4 * 4;
}

struct AlignedFree {
  void operator()(std::uint8_t* p) const { std::free(p); }
};
using AlignedBytes = std::unique_ptr<std::uint8_t, AlignedFree>;

AlignedBytes AllocateAligned(std::size_t bytes) {
  return AlignedBytes(static_cast<std::uint8_t*>(std::aligned_alloc(kBlock, RoundUp(bytes))));
}

// Writes all `bytes` at `offset`, resuming after short writes.
int PwriteFull(int fd, const std::uint8_t* data, std::size_t bytes, off_t offset) {
  while (bytes > 0) {
    const ssize_t done = ::pwrite(fd, data, bytes, offset);
    if (done < 0 && errno == EINTR) continue;
    if (done < 0) return errno;
    if (done == 0) return EIO;
    data += done;
    bytes -= static_cast<std::size_t>(done);
    offset += done;
  }
  return 0;
}

// Writes the pixels (`pixels`, `pixel_write_bytes` long, aligned) and then the
// header block; 0 or the errno of the first failure.
int WriteFile(int fd, const std::uint8_t* header, const std::uint8_t* pixels,
              std::size_t pixel_write_bytes, std::size_t file_bytes) {
  if (int e = PwriteFull(fd, pixels, pixel_write_bytes, kRawBmpPixelOffset); e != 0) return e;
  if (int e = PwriteFull(fd, header, kBlock, 0); e != 0) return e;
  if (::ftruncate(fd, static_cast<off_t>(file_bytes)) != 0) return errno;
  return 0;
}

}  // namespace

void FillRawBmpHeaderBlock(int width, int height, PixelFormat format, std::uint8_t* block) {
  std::memset(block, 0, kBlock);
  FormatBmpHeader(width, height, format, /*top_down=*/true, kRawBmpPixelOffset, block);
}

std::size_t RawBmpFileBytes(int width, int height, PixelFormat format) {
  return kRawBmpPixelOffset + PaddedRowBytes(width, format) * static_cast<std::size_t>(height);
}

Expected<RawFrameWriteResult> WriteRawFrame(const std::filesystem::path& path, const Frame& frame,
                                            bool try_direct, int* error_number) {
  if (error_number != nullptr) *error_number = 0;
  const ImageView& image = frame.image;
  if (image.data == nullptr || image.width <= 0 || image.height <= 0) {
    if (error_number != nullptr) *error_number = EINVAL;
    return MakeError(
        path.string(), 0, 0,
        "frame " + std::to_string(frame.frame_id) + " of camera " + frame.serial + " has no image");
  }
  const std::size_t row_bytes = PaddedRowBytes(image.width, image.format);
  const std::size_t pixel_bytes = row_bytes * static_cast<std::size_t>(image.height);
  const std::size_t file_bytes = kRawBmpPixelOffset + pixel_bytes;

  // The pooled buffer can be written as it is when its rows already have the
  // BMP's padded row size, it is aligned and it holds the 4096-padded length.
  const std::uint8_t* pixels = image.data;
  AlignedBytes staging;
  const bool in_buffer =
      frame.buffer && image.data >= frame.buffer->data &&
      image.data + RoundUp(pixel_bytes) <= frame.buffer->data + frame.buffer->capacity_bytes;
  const bool writable_as_is = image.stride_bytes == row_bytes && in_buffer &&
                              reinterpret_cast<std::uintptr_t>(image.data) % kBlock == 0;
  if (!writable_as_is) {
    // Decision: odd strides or foreign memory go through one aligned copy.
    staging = AllocateAligned(pixel_bytes);
    if (!staging) {
      if (error_number != nullptr) *error_number = ENOMEM;
      return MakeError(path.string(), 0, 0, "out of memory for a staging row buffer");
    }
    std::memset(staging.get(), 0, RoundUp(pixel_bytes));
    for (int y = 0; y < image.height; ++y) {
      std::memcpy(staging.get() + static_cast<std::size_t>(y) * row_bytes, image.Row(y),
                  image.RowBytes());
    }
    pixels = staging.get();
  }

  // One header block per thread: aligned for O_DIRECT, reused for every frame.
  thread_local AlignedBytes header = AllocateAligned(kBlock);
  if (!header) {
    if (error_number != nullptr) *error_number = ENOMEM;
    return MakeError(path.string(), 0, 0, "out of memory for the header block");
  }
  FillRawBmpHeaderBlock(image.width, image.height, image.format, header.get());

  const std::string name = path.string();
  auto fail = [&](int e, const std::string& what) -> Expected<RawFrameWriteResult> {
    ::unlink(name.c_str());
    if (error_number != nullptr) *error_number = e;
    return MakeError(name, 0, 0, what + ": " + std::strerror(e));
  };

  if (try_direct) {
    FileDescriptor fd(
        ::open(name.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_DIRECT | O_CLOEXEC, 0644));
    if (fd.get() >= 0) {
      const int e = WriteFile(fd.get(), header.get(), pixels, RoundUp(pixel_bytes), file_bytes);
      if (e == 0) {
        if (fd.Close() != 0) return fail(errno, "close after writing failed");
        return RawFrameWriteResult{WritePath::kDirect, file_bytes};
      }
      // EINVAL: the file system accepted the open flag but not the direct write.
      if (e != EINVAL) return fail(e, "write failed");
    } else if (errno != EINVAL) {
      return fail(errno, "cannot create");
    }
  }
  FileDescriptor fd(::open(name.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (fd.get() < 0) return fail(errno, "cannot create");
  if (int e = WriteFile(fd.get(), header.get(), pixels, pixel_bytes, file_bytes); e != 0)
    return fail(e, "write failed");
  if (fd.Close() != 0) return fail(errno, "close after writing failed");
  return RawFrameWriteResult{WritePath::kBuffered, file_bytes};
}

}  // namespace lifmcr
