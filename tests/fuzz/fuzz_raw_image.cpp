// Raw frames in the containers other tools write (PNG, TIFF, BMP) through
// ReadRawImage on a real file descriptor: the container sniffing, the PNG
// IHDR and TIFF directory size checks made before OpenCV decodes, the 16-bit
// scale to 8 bits.

#include "replay/raw_image.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  fuzz::MemFile file(data, size);
  RawImageInfo info;
  Expected<OwnedImage> image = ReadRawImage(file.path(), &info);
  if (!image) return 0;
  const ConstImageView view = image->View();
  fuzz::Require(view.width > 0 && view.height > 0, "an accepted image has a positive size");
  fuzz::Require(info.significant_bits >= 8 && info.significant_bits <= info.file_bits,
                "the reported scale keeps at most the file's bits");
  (void)info.Describe();
  return 0;
}
