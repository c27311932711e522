#pragma once
// Devignetting without a white image (RxLive "Processed" exports, public
// datasets that ship no white image): what the frame itself says.
//
// The mean micro image: m(r) = mean over the frame's pixels at distance r
// from their micro image's centre c_k (MlaGrid::Nearest), in bins of
// `bin_px`. Scene texture averages out over thousands of micro images, so
// m(r) / m(0) is the micro lenses' own vignetting (main-lens field falloff,
// the same for neighbouring micro images, is not estimated).
// - If m(r) >= flat_fraction * m(0) for every r <= r_valid
//   (= D/2 - lens_border), the frame is taken as already devignetted: no
//   gain, every pixel within r_valid valid.
// - Otherwise a white image W(p) = 255 m(r(p)) / max m is built from the
//   profile and the frame is devignetted by it as by a real white image
//   (plenoptic_frame.h: gain W_ref / W, invalid below min_white_fraction).

#include "config/error.h"
#include "config/image.h"
#include "config/mla.h"
#include "processing/mla_grid.h"

#include <cstdint>
#include <string>
#include <vector>

namespace lifmcr::processing {

struct VignettingOptions {
  double bin_px = 0.25;         // radial bin of the profile
  double flat_fraction = 0.95;  // m(r) / m(0) above this out to r_valid: already corrected
  int row_step = 1;             // every row_step-th row is sampled (R32: 4 is plenty)
  Status Check() const;
};

struct VignettingEstimate {
  bool already_corrected = false;
  double bin_px = 0.25;
  std::vector<double> profile;  // m(r) / m(0), bins up to D/2
  double radius_valid_px = 0;   // r_valid of the MLA file
  double min_ratio = 1;         // min of m(r) / m(0) for r <= r_valid
  int width = 0, height = 0;
  std::vector<std::uint8_t> white;  // Mono8, width x height; empty when already corrected
  // The white image to devignette with; an empty view (data == nullptr)
  // when the frame is already corrected.
  ConstImageView White() const;
  // One line: which of the two it decided, and why.
  std::string BriefReport() const;
};

Expected<VignettingEstimate> EstimateVignetting(ConstImageView raw, const MlaGrid& grid,
                                                const MlaCalibration& mla,
                                                const VignettingOptions& options = {});

}  // namespace lifmcr::processing
