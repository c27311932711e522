#include "replay/bmp.h"

#include "config/input_file.h"
#include "config/text_escape.h"
#include "replay/file_descriptor.h"

#include <climits>
#include <cstdlib>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

namespace lifmcr {
namespace {

static_assert(sizeof(std::size_t) >= 8, "BMP sizes need 64-bit size_t");

constexpr std::size_t kFileHeaderBytes = 14;
constexpr std::size_t kInfoHeaderBytes = 40;
constexpr std::size_t kMaxDibHeaderBytes = 124;
constexpr std::size_t kPaletteEntries = 256;
constexpr std::size_t kMaxHeaderPrefix =
    kFileHeaderBytes + kMaxDibHeaderBytes + 4 * kPaletteEntries;
// Row padding is at most 3 bytes; every padding iovec reads into (or writes
// from) this many bytes.
constexpr std::size_t kMaxPadding = 3;

#ifdef IOV_MAX
constexpr int kIovMax = IOV_MAX;
#else
constexpr int kIovMax = 1024;
#endif

std::string Errno() { return std::strerror(errno); }

constexpr InputLimits kBmpInput{"a raw frame (BMP, 8-bit grey or 24-bit BGR)",
                                kBmpLimits.max_file_bytes};

std::uint16_t U16(std::span<const std::uint8_t> b, std::size_t at) {
  return static_cast<std::uint16_t>(b[at] | (b[at + 1] << 8));
}
std::uint32_t U32(std::span<const std::uint8_t> b, std::size_t at) {
  return static_cast<std::uint32_t>(b[at]) | (static_cast<std::uint32_t>(b[at + 1]) << 8) |
         (static_cast<std::uint32_t>(b[at + 2]) << 16) |
         (static_cast<std::uint32_t>(b[at + 3]) << 24);
}
std::int32_t I32(std::span<const std::uint8_t> b, std::size_t at) {
  return static_cast<std::int32_t>(U32(b, at));
}

void PutU16(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void PutU32(std::uint8_t* p, std::uint32_t v) {
  PutU16(p, v);
  PutU16(p + 2, v >> 16);
}

std::string CompressionName(std::uint32_t compression) {
  switch (compression) {
    case 1:
      return "BI_RLE8";
    case 2:
      return "BI_RLE4";
    case 3:
      return "BI_BITFIELDS";
    case 4:
      return "BI_JPEG";
    case 5:
      return "BI_PNG";
    case 6:
      return "BI_ALPHABITFIELDS";
    default:
      return "unknown";
  }
}

std::size_t PaddedRowBytes(std::size_t width, int bytes_per_pixel) {
  return (width * static_cast<std::size_t>(bytes_per_pixel) + 3) / 4 * 4;
}

// Error at a byte offset and field of the header: "<file>: byte 28 (bits per pixel): <what>".
Error FieldError(const std::string& file, std::size_t offset, const std::string& field,
                 const std::string& what) {
  return MakeErrorAt(file, "byte " + std::to_string(offset) + " (" + field + ")", what);
}

Error TruncatedError(const std::string& file, std::size_t expected, std::size_t actual,
                     const std::string& why) {
  return MakeError(file, 0, 0,
                   "truncated BMP: expected at least " + std::to_string(expected) + " bytes (" +
                       why + "), the file has " + std::to_string(actual));
}

// Index of the first iovec with bytes left after `done` more bytes went
// through iov[first...]; a partly done iovec is shortened in place.
std::size_t Advance(std::vector<iovec>& iov, std::size_t first, std::size_t done) {
  while (first < iov.size() && (done > 0 || iov[first].iov_len == 0)) {
    if (done >= iov[first].iov_len) {
      done -= iov[first].iov_len;
      ++first;
    } else {
      iov[first].iov_base = static_cast<std::uint8_t*>(iov[first].iov_base) + done;
      iov[first].iov_len -= done;
      done = 0;
    }
  }
  return first;
}

// Reads exactly the bytes the iovecs describe, starting at `offset`, calling
// preadv at most IOV_MAX iovecs at a time and resuming after short reads. The
// iovecs are consumed (modified) on the way.
Status PreadvFull(int fd, std::vector<iovec>& iov, off_t offset, const std::string& file) {
  for (std::size_t first = Advance(iov, 0, 0); first < iov.size();) {
    const int count = static_cast<int>(std::min<std::size_t>(kIovMax, iov.size() - first));
    const ssize_t got = ::preadv(fd, &iov[first], count, offset);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      return MakeError(file, 0, 0,
                       "read failed at byte " + std::to_string(offset) + ": " + Errno());
    }
    if (got == 0) {
      return MakeError(file, 0, 0,
                       "truncated BMP: end of file at byte " + std::to_string(offset) +
                           " before the last row (the file changed after its header was read?)");
    }
    offset += got;
    first = Advance(iov, first, static_cast<std::size_t>(got));
  }
  return Status::Ok();
}

// The write counterpart of PreadvFull.
Status PwritevFull(int fd, std::vector<iovec>& iov, off_t offset, const std::string& file) {
  for (std::size_t first = Advance(iov, 0, 0); first < iov.size();) {
    const int count = static_cast<int>(std::min<std::size_t>(kIovMax, iov.size() - first));
    const ssize_t put = ::pwritev(fd, &iov[first], count, offset);
    if (put < 0 && errno == EINTR) continue;
    if (put <= 0) {
      return MakeError(file, 0, 0,
                       "write failed at byte " + std::to_string(offset) + ": " +
                           (put < 0 ? Errno() : std::string("nothing written")));
    }
    offset += put;
    first = Advance(iov, first, static_cast<std::size_t>(put));
  }
  return Status::Ok();
}

Status ReadFull(int fd, std::uint8_t* dst, std::size_t bytes, off_t offset,
                const std::string& file) {
  std::vector<iovec> iov{{dst, bytes}};
  return PreadvFull(fd, iov, offset, file);
}

std::string Shape(int width, int height, PixelFormat format) {
  return std::to_string(width) + "x" + std::to_string(height) + " " + std::string(ToString(format));
}

}  // namespace

std::string BmpHeader::Describe() const {
  return Shape(width, height, format) + (top_down ? " top-down" : " bottom-up") + ", rows of " +
         std::to_string(file_row_bytes) + " bytes at offset " + std::to_string(pixel_offset) +
         (palette_is_grey ? "" : ", non-grey palette (ignored)");
}

Expected<BmpHeader> ParseBmpHeader(std::span<const std::uint8_t> prefix, std::size_t file_size,
                                   const std::string& file_name) {
  const std::string& f = file_name;
  if (prefix.size() > file_size) prefix = prefix.first(file_size);
  if (prefix.size() < 2) {
    return TruncatedError(f, kFileHeaderBytes + kInfoHeaderBytes, file_size, "BMP headers");
  }
  if (prefix[0] != 'B' || prefix[1] != 'M') {
    char got[16];
    std::snprintf(got, sizeof(got), "0x%02X 0x%02X", prefix[0], prefix[1]);
    return FieldError(f, 0, "magic", std::string("not a BMP file: expected 'BM', got ") + got);
  }
  if (prefix.size() < kFileHeaderBytes + 4) {
    return TruncatedError(f, kFileHeaderBytes + kInfoHeaderBytes, file_size, "BMP headers");
  }
  const std::uint32_t declared_size = U32(prefix, 2);
  const std::uint32_t pixel_offset = U32(prefix, 10);
  const std::uint32_t dib_bytes = U32(prefix, 14);
  if (dib_bytes == 12 || dib_bytes == 16 || dib_bytes == 64) {
    return FieldError(f, 14, "DIB header size",
                      "OS/2 BMP header of " + std::to_string(dib_bytes) +
                          " bytes is not supported; expected 40 (BITMAPINFOHEADER), 52, 56, "
                          "108 (V4) or 124 (V5)");
  }
  if (dib_bytes != 40 && dib_bytes != 52 && dib_bytes != 56 && dib_bytes != 108 &&
      dib_bytes != 124) {
    return FieldError(f, 14, "DIB header size",
                      "got " + std::to_string(dib_bytes) +
                          ", expected 40 (BITMAPINFOHEADER), 52, 56, 108 (V4) or 124 (V5)");
  }
  if (prefix.size() < kFileHeaderBytes + dib_bytes) {
    return TruncatedError(f, kFileHeaderBytes + dib_bytes, file_size,
                          std::to_string(dib_bytes) + "-byte DIB header");
  }
  if (declared_size != 0 && declared_size > file_size) {
    return FieldError(f, 2, "file size",
                      "truncated BMP: the header says the file has " +
                          std::to_string(declared_size) + " bytes, it has " +
                          std::to_string(file_size));
  }

  const std::int32_t width = I32(prefix, 18);
  const std::int32_t signed_height = I32(prefix, 22);
  const std::uint16_t planes = U16(prefix, 26);
  const std::uint16_t bits = U16(prefix, 28);
  const std::uint32_t compression = U32(prefix, 30);
  const std::uint32_t colours_used = U32(prefix, 46);

  if (width <= 0 || width > kBmpLimits.max_side_px) {
    return FieldError(f, 18, "width",
                      "got " + std::to_string(width) + ", expected 1 .. " +
                          std::to_string(kBmpLimits.max_side_px) + " px (a real sensor)");
  }
  if (signed_height == 0 || signed_height == INT32_MIN ||
      std::abs(signed_height) > kBmpLimits.max_side_px) {
    return FieldError(f, 22, "height",
                      "got " + std::to_string(signed_height) +
                          ", expected a row count of 1 .. " +
                          std::to_string(kBmpLimits.max_side_px) +
                          " (> 0 bottom-up, < 0 top-down)");
  }
  if (static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(std::abs(signed_height)) >
      kBmpLimits.max_pixels) {
    return FieldError(f, 18, "width",
                      std::to_string(width) + "x" + std::to_string(std::abs(signed_height)) +
                          " px is more than the " + std::to_string(kBmpLimits.max_pixels / 1000000) +
                          " megapixels of any real sensor");
  }
  if (planes != 1) {
    return FieldError(f, 26, "planes", "got " + std::to_string(planes) + ", expected 1");
  }
  if (bits != 8 && bits != 24) {
    return FieldError(
        f, 28, "bits per pixel",
        std::to_string(bits) + "-bit BMP is not supported; expected 8 (grey) or 24 (BGR)");
  }
  if (compression != 0) {
    return FieldError(f, 30, "compression",
                      "compressed BMP (" + std::to_string(compression) + " = " +
                          CompressionName(compression) +
                          ") is not supported; expected 0 (BI_RGB, uncompressed)");
  }

  BmpHeader header;
  header.width = width;
  header.height = signed_height < 0 ? -signed_height : signed_height;
  header.top_down = signed_height < 0;
  header.format = bits == 8 ? PixelFormat::kMono8 : PixelFormat::kBgr8;
  header.file_row_bytes = PaddedRowBytes(static_cast<std::size_t>(width), bits / 8);
  header.pixel_offset = pixel_offset;
  header.file_size = file_size;
  header.dib_header_bytes = static_cast<int>(dib_bytes);

  std::size_t header_end = kFileHeaderBytes + dib_bytes;
  if (bits == 8) {
    if (colours_used > kPaletteEntries) {
      return FieldError(f, 46, "colours used",
                        "got " + std::to_string(colours_used) + ", expected at most 256");
    }
    const std::size_t entries = colours_used == 0 ? kPaletteEntries : colours_used;
    const std::size_t palette_at = header_end;
    header_end += 4 * entries;
    if (header_end > file_size || header_end > prefix.size()) {
      return TruncatedError(f, header_end, file_size,
                            "headers and a palette of " + std::to_string(entries) + " entries");
    }
    for (std::size_t i = 0; i < entries; ++i) {
      const std::size_t at = palette_at + 4 * i;
      const auto grey = static_cast<std::uint8_t>(i);
      if (prefix[at] != grey || prefix[at + 1] != grey || prefix[at + 2] != grey) {
        header.palette_is_grey = false;
        break;
      }
    }
  }
  if (pixel_offset < header_end) {
    return FieldError(f, 10, "pixel offset",
                      "got " + std::to_string(pixel_offset) +
                          ", which lies inside the headers and palette; expected >= " +
                          std::to_string(header_end));
  }
  const std::size_t needed = header.pixel_offset + header.PixelBytes();
  if (needed > file_size) {
    return TruncatedError(f, needed, file_size,
                          "pixel data at byte " + std::to_string(pixel_offset) + " + " +
                              std::to_string(header.height) + " rows of " +
                              std::to_string(header.file_row_bytes) + " bytes");
  }
  return header;
}

Expected<BmpHeader> ReadBmpHeader(const std::filesystem::path& path) {
  const std::string file = EscapeText(path.string());
  Expected<InputFile> opened = OpenInputFile(path, kBmpInput);
  if (!opened) return opened.error();
  FileDescriptor fd(opened->fd);
  const auto file_size = static_cast<std::size_t>(opened->size_bytes);
  std::array<std::uint8_t, kMaxHeaderPrefix> prefix{};
  const std::size_t prefix_bytes = std::min(file_size, prefix.size());
  if (Status read = ReadFull(fd.get(), prefix.data(), prefix_bytes, 0, file); !read.ok()) {
    return read.error();
  }
  return ParseBmpHeader(std::span(prefix.data(), prefix_bytes), file_size, file);
}

Status ReadBmpInto(const std::filesystem::path& path, const BmpHeader& header, ImageView dst) {
  const std::string file = EscapeText(path.string());
  if (dst.width != header.width || dst.height != header.height || dst.format != header.format) {
    return MakeError(file, 0, 0,
                     "frame is " + Shape(header.width, header.height, header.format) +
                         ", buffer is " + Shape(dst.width, dst.height, dst.format));
  }
  if (header.width <= 0 || header.height <= 0) {
    return MakeError(file, 0, 0,
                     "invalid header: " + Shape(header.width, header.height, header.format) +
                         " frame; expected one from ReadBmpHeader");
  }
  const std::size_t row_bytes = dst.RowBytes();
  if (dst.data == nullptr || dst.stride_bytes < row_bytes) {
    return MakeError(file, 0, 0,
                     "buffer for a " + Shape(header.width, header.height, header.format) +
                         " frame needs rows of at least " + std::to_string(row_bytes) +
                         " bytes, its stride is " + std::to_string(dst.stride_bytes) +
                         (dst.data == nullptr ? " and it has no memory" : ""));
  }
  if (header.file_row_bytes != PaddedRowBytes(header.width, BytesPerPixel(header.format))) {
    return MakeError(file, 0, 0,
                     "inconsistent header: rows of " + std::to_string(header.file_row_bytes) +
                         " bytes for a " + Shape(header.width, header.height, header.format) +
                         " frame");
  }

  // The file is opened again (it may have changed since its header was
  // read): the same checks, never a blocking open of a FIFO.
  Expected<InputFile> opened = OpenInputFile(path, kBmpInput);
  if (!opened) return opened.error();
  FileDescriptor fd(opened->fd);
  const std::size_t needed = header.pixel_offset + header.PixelBytes();
  if (opened->size_bytes < needed) {
    return TruncatedError(file, needed, static_cast<std::size_t>(opened->size_bytes),
                          "the header read before says so");
  }
  const auto offset = static_cast<off_t>(header.pixel_offset);
  const auto height = static_cast<std::size_t>(header.height);

  // The file's rows already have dst's layout: one read. The last row's
  // padding is not read, as dst need not own memory past its last row.
  if (header.top_down && dst.stride_bytes == header.file_row_bytes) {
    return ReadFull(fd.get(), dst.data, header.file_row_bytes * (height - 1) + row_bytes, offset,
                    file);
  }

  const std::size_t padding = header.file_row_bytes - row_bytes;
  std::array<std::uint8_t, kMaxPadding> scratch{};
  std::vector<iovec> iov;
  iov.reserve(height * (padding > 0 ? 2 : 1));
  for (std::size_t r = 0; r < height; ++r) {
    const std::size_t y = header.top_down ? r : height - 1 - r;
    iov.push_back({dst.data + y * dst.stride_bytes, row_bytes});
    if (padding > 0) iov.push_back({scratch.data(), padding});
  }
  return PreadvFull(fd.get(), iov, offset, file);
}

Expected<OwnedImage> ReadBmp(const std::filesystem::path& path) {
  Expected<BmpHeader> header = ReadBmpHeader(path);
  if (!header) return header.error();
  OwnedImage image = OwnedImage::Allocate(header->width, header->height, header->format);
  if (Status read = ReadBmpInto(path, *header, image.View()); !read.ok()) return read.error();
  return image;
}

std::size_t BmpHeaderBytes(PixelFormat format) {
  return kFileHeaderBytes + kInfoHeaderBytes +
         (format == PixelFormat::kMono8 ? 4 * kPaletteEntries : 0);
}

void FormatBmpHeader(int width, int height, PixelFormat format, bool top_down,
                     std::size_t pixel_offset, std::uint8_t* p) {
  const bool mono = format == PixelFormat::kMono8;
  const std::size_t pixel_bytes =
      PaddedRowBytes(width, BytesPerPixel(format)) * static_cast<std::size_t>(height);
  std::memset(p, 0, BmpHeaderBytes(format));
  p[0] = 'B';
  p[1] = 'M';
  PutU32(p + 2, static_cast<std::uint32_t>(pixel_offset + pixel_bytes));
  PutU32(p + 10, static_cast<std::uint32_t>(pixel_offset));
  PutU32(p + 14, kInfoHeaderBytes);
  PutU32(p + 18, static_cast<std::uint32_t>(width));
  PutU32(p + 22, static_cast<std::uint32_t>(top_down ? -height : height));
  PutU16(p + 26, 1);
  PutU16(p + 28, mono ? 8 : 24);
  PutU32(p + 30, 0);  // BI_RGB
  PutU32(p + 34, static_cast<std::uint32_t>(pixel_bytes));
  PutU32(p + 38, 2835);  // 72 dpi, what most writers put
  PutU32(p + 42, 2835);
  PutU32(p + 46, mono ? kPaletteEntries : 0);
  PutU32(p + 50, 0);
  if (mono) {
    for (std::size_t i = 0; i < kPaletteEntries; ++i) {
      std::uint8_t* entry = p + kFileHeaderBytes + kInfoHeaderBytes + 4 * i;
      entry[0] = entry[1] = entry[2] = static_cast<std::uint8_t>(i);
    }
  }
}

Status WriteBmp(const std::filesystem::path& path, ConstImageView image, bool top_down) {
  const std::string file = path.string();
  if (image.width <= 0 || image.height <= 0 || image.data == nullptr ||
      image.stride_bytes < image.RowBytes()) {
    return MakeError(file, 0, 0,
                     "cannot write a " + Shape(image.width, image.height, image.format) +
                         " image with a stride of " + std::to_string(image.stride_bytes) +
                         " bytes: expected width and height > 0, pixels, and a stride >= " +
                         std::to_string(image.RowBytes()));
  }
  const bool mono = image.format == PixelFormat::kMono8;
  const std::size_t row_bytes = image.RowBytes();
  const std::size_t file_row_bytes = PaddedRowBytes(image.width, BytesPerPixel(image.format));
  const std::size_t pixel_offset =
      kFileHeaderBytes + kInfoHeaderBytes + (mono ? 4 * kPaletteEntries : 0);
  const std::size_t file_size = pixel_offset + file_row_bytes * image.height;
  if (file_size > UINT32_MAX) {
    return MakeError(file, 0, 0,
                     "a " + Shape(image.width, image.height, image.format) + " BMP needs " +
                         std::to_string(file_size) + " bytes, more than the format's 4 GiB");
  }

  std::array<std::uint8_t, kFileHeaderBytes + kInfoHeaderBytes + 4 * kPaletteEntries> head{};
  FormatBmpHeader(image.width, image.height, image.format, top_down, pixel_offset, head.data());

  const std::size_t padding = file_row_bytes - row_bytes;
  static const std::array<std::uint8_t, kMaxPadding> kZeros{};
  const auto height = static_cast<std::size_t>(image.height);
  std::vector<iovec> iov;
  iov.reserve(1 + height * (padding > 0 ? 2 : 1));
  iov.push_back({head.data(), pixel_offset});
  for (std::size_t r = 0; r < height; ++r) {
    const std::size_t y = top_down ? r : height - 1 - r;
    // pwritev only reads through iov_base; the cast drops const for the C API.
    iov.push_back({const_cast<std::uint8_t*>(image.Row(static_cast<int>(y))), row_bytes});
    if (padding > 0) iov.push_back({const_cast<std::uint8_t*>(kZeros.data()), padding});
  }

  FileDescriptor fd(::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (fd.get() < 0) return MakeError(file, 0, 0, "cannot create BMP: " + Errno());
  Status written = PwritevFull(fd.get(), iov, 0, file);
  if (written.ok() && fd.Close() != 0) {
    written = MakeError(file, 0, 0, "closing after writing failed: " + Errno());
  }
  if (!written.ok()) {
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  }
  return written;
}

}  // namespace lifmcr
