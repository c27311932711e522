// BMP header and pixels: ReadBmpHeader + ReadBmpInto through a real file
// descriptor, so the open/size checks of config/input_file.h run too.

#include "replay/bmp.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  // The header parser on the bytes alone (any declared file size).
  (void)ParseBmpHeader(std::span(data, size), size, "fuzz.bmp");
  fuzz::MemFile file(data, size);
  Expected<BmpHeader> header = ReadBmpHeader(file.path());
  if (!header) return 0;
  fuzz::Require(header->width > 0 && header->height > 0, "accepted header has a positive size");
  fuzz::Require(header->pixel_offset + header->PixelBytes() <= size,
                "accepted header's pixels lie inside the file");
  Expected<OwnedImage> image = ReadBmp(file.path());
  fuzz::Require(image.ok(), "a file whose header was accepted reads");
  return 0;
}
