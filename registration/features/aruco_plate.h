#pragma once
// The ArUco markers of the plate on a TF image (OpenCV aruco finds them,
// marker_edges.h places their corners from line fits to the border's edges):
// each detected corner with its known position in the plate frame, the
// metric anchor of calibration (scale and world frame).

#include "config/error.h"
#include "config/image.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/features/marker_edges.h"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace lifmcr::registration {

struct PlateCorner {
  int marker_id = 0;
  int corner = 0;          // 0..3, OpenCV order (PlateLayout::Corner)
  Eigen::Vector2d tf_px;   // detected corner on the TF grid
  Eigen::Vector3d p_in_w_mm;  // known position in the plate frame
};

// A marker as OpenCV aruco finds it: its id and its four corners (OpenCV
// order; ArUco's own sub-pixel corners, the start of the edge fits).
struct PlateMarker {
  int marker_id = 0;
  std::array<Eigen::Vector2d, 4> quad;
};

// Markers of the layout's dictionary whose id the layout holds; other ids
// are ignored.
Expected<std::vector<PlateMarker>> FindPlateMarkers(ConstImageView tf_image,
                                                    const PlateLayout& layout);

// The corners of `markers` placed by marker_edges.h on `tf_image` (the
// image they were found on, or one of the same TF grid, e.g. rendered at
// other depths); a marker whose edges do not fit a square's (partly
// occluded, or a wrong quad) is left out. `edges` as given, but for its
// cells_per_side, which the layout's dictionary sets.
Expected<std::vector<PlateCorner>> RefinePlateCorners(ConstImageView tf_image,
                                                      const PlateLayout& layout,
                                                      const std::vector<PlateMarker>& markers,
                                                      const MarkerEdgeOptions& edges = {});

// FindPlateMarkers, then RefinePlateCorners on the same image.
Expected<std::vector<PlateCorner>> DetectPlateCorners(ConstImageView tf_image,
                                                      const PlateLayout& layout);

}  // namespace lifmcr::registration
