#include "registration/features/aruco_plate.h"

#include "registration/features/marker_edges.h"

#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace lifmcr::registration {
namespace {

// The image as 8-bit grey (a view of it when it is grey already).
cv::Mat Grey(ConstImageView image) {
  const int type = image.format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  const cv::Mat view(image.height, image.width, type, const_cast<std::uint8_t*>(image.data),
                     image.stride_bytes);
  if (type == CV_8UC1) return view;
  cv::Mat grey;
  cv::cvtColor(view, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

}  // namespace

Expected<std::vector<PlateMarker>> FindPlateMarkers(ConstImageView image,
                                                    const PlateLayout& layout) {
  if (image.data == nullptr) return Error{"ArUco: empty image"};
  const cv::Mat grey = Grey(image);
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  try {
    const cv::Ptr<cv::aruco::Dictionary> dictionary =
        cv::aruco::getPredefinedDictionary(layout.aruco_dictionary);
    cv::Ptr<cv::aruco::DetectorParameters> parameters = cv::aruco::DetectorParameters::create();
    parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    cv::aruco::detectMarkers(grey, dictionary, corners, ids, parameters);
  } catch (const cv::Exception& e) {
    return Error{std::string("ArUco: ") + e.what()};
  }
  std::vector<PlateMarker> out;
  for (std::size_t m = 0; m < ids.size(); ++m) {
    if (!layout.aruco_centers_mm.count(ids[m])) continue;
    PlateMarker marker;
    marker.marker_id = ids[m];
    for (int c = 0; c < 4; ++c) marker.quad[c] = Eigen::Vector2d(corners[m][c].x, corners[m][c].y);
    out.push_back(marker);
  }
  return out;
}

Expected<std::vector<PlateCorner>> RefinePlateCorners(ConstImageView image,
                                                      const PlateLayout& layout,
                                                      const std::vector<PlateMarker>& markers,
                                                      const MarkerEdgeOptions& edges) {
  if (image.data == nullptr) return Error{"ArUco: empty image"};
  if (Status s = edges.Check(); !s) return s.error();
  const cv::Mat grey = Grey(image);
  int dictionary_cells = 6;
  try {
    dictionary_cells = cv::aruco::getPredefinedDictionary(layout.aruco_dictionary)->markerSize;
  } catch (const cv::Exception& e) {
    return Error{std::string("ArUco: ") + e.what()};
  }
  // ArUco's corners start the edge fits of marker_edges.h (cornerSubPix
  // alone sits inside blurred oblique corners); a marker whose edges do not
  // fit (occluded, a wrong quad) is left out rather than kept biased.
  const ConstImageView grey_view(grey.data, grey.cols, grey.rows, grey.step, PixelFormat::kMono8);
  MarkerEdgeOptions edge_options = edges;
  edge_options.cells_per_side = dictionary_cells + 2;
  std::vector<PlateCorner> out;
  for (const PlateMarker& marker : markers) {
    if (!layout.aruco_centers_mm.count(marker.marker_id)) continue;
    std::array<Eigen::Vector2d, 4> quad = marker.quad;
    if (!RefineMarkerCorners(grey_view, edge_options, &quad)) continue;
    for (int c = 0; c < 4; ++c)
      out.push_back(
          PlateCorner{marker.marker_id, c, quad[c], layout.Corner(marker.marker_id, c)});
  }
  return out;
}

Expected<std::vector<PlateCorner>> DetectPlateCorners(ConstImageView image,
                                                      const PlateLayout& layout) {
  Expected<std::vector<PlateMarker>> markers = FindPlateMarkers(image, layout);
  if (!markers) return markers.error();
  return RefinePlateCorners(image, layout, *markers);
}

}  // namespace lifmcr::registration
