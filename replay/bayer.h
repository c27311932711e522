#pragma once
// Bayer mosaics (GenICam BayerRG8/GR8/GB8/BG8: the colours of the first two
// pixels of the first row) demosaiced to BGR8 with OpenCV's edge-aware
// interpolation, for the TF image and previews in colour. Depth runs on the
// luminance of the demosaiced image (processing/ takes the channel mean).
//
// The one copy: the 3-byte BGR image the caller provides (a mosaic cannot be
// shown or rendered in colour in place).

#include "config/error.h"
#include "config/image.h"
#include "config/rig_config.h"

namespace lifmcr {

bool IsBayer(CameraPixelFormat format);

// `mosaic` (Mono8) into `bgr` (BGR8, same size). An error when `pattern` is
// not a Bayer format or the sizes or formats do not match.
Status DemosaicBayer(ConstImageView mosaic, CameraPixelFormat pattern, ImageView bgr);

}  // namespace lifmcr
