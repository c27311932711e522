// MLA calibration XML, then what processing does with an accepted file:
// the lattice over an image and the frame preparation (where unchecked
// values used to crash).

#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "replay/bmp.h"
#include "replay/mla_xml.h"
#include "tests/fuzz/fuzz_util.h"

#include <algorithm>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  if (size < 2) return 0;
  // First two bytes: the image size the calibration is used with.
  const int width = 16 + data[0];
  const int height = 16 + data[1];
  Expected<MlaCalibration> mla = ParseMlaXml(fuzz::Text(data + 2, size - 2), "fuzz.xml");
  if (!mla) return 0;
  fuzz::Require(CheckMlaCalibration(*mla).ok(), "a parsed calibration passes the checks");
  Expected<MlaCalibration> again = ParseMlaXml(FormatMlaXml(*mla), "again.xml");
  fuzz::Require(again.ok(), "a written calibration reads back");
  const processing::MlaGrid grid = processing::MlaGrid::FromCalibration(*mla, width, height);
  OwnedImage raw = OwnedImage::Allocate(width, height, PixelFormat::kMono8);
  OwnedImage white = OwnedImage::Allocate(width, height, PixelFormat::kMono8);
  std::fill(raw.pixels.begin(), raw.pixels.end(), 100);
  std::fill(white.pixels.begin(), white.pixels.end(), 200);
  processing::PlenopticFrame frame;
  (void)processing::PrepareFrame(raw.View(), white.View(), grid, *mla, processing::FrameOptions{},
                                 &frame);
  return 0;
}
