#include "config/mla.h"

namespace lifmcr {

Eigen::Vector2d MlaCalibration::ReferenceLensCenterPx(int width, int height) const {
  return {(width - 1) / 2.0 + offset_px.x(), (height - 1) / 2.0 - offset_px.y()};
}

}  // namespace lifmcr
