// The only file of the generator that draws ArUco markers (OpenCV aruco).
#include "replay/synth/marker_plate.h"

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace lifmcr::synth {

std::array<Eigen::Vector3d, 4> MarkerPlateLayout::ViconMarkers() const {
  return {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(vicon_span_x_mm, 0, 0),
          Eigen::Vector3d(vicon_span_x_mm, vicon_span_y_mm, 0),
          Eigen::Vector3d(0, vicon_span_y_mm, 0)};
}

double PlateBitmap::Sample(double x_mm, double y_mm) const {
  const double col = (x_mm - min_mm.x()) * px_per_mm - 0.5;
  const double row = (height - 1 + 0.5) - (y_mm - min_mm.y()) * px_per_mm;
  if (col < -0.5 || row < -0.5 || col > width - 0.5 || row > height - 0.5) return -1.0;
  const double cx = std::clamp(col, 0.0, width - 1.0), cy = std::clamp(row, 0.0, height - 1.0);
  const int x0 = std::min(static_cast<int>(cx), width - 2),
            y0 = std::min(static_cast<int>(cy), height - 2);
  const double tx = cx - x0, ty = cy - y0;
  auto at = [&](int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x] / 255.0; };
  const double top = at(x0, y0) + (at(x0 + 1, y0) - at(x0, y0)) * tx;
  const double bottom = at(x0, y0 + 1) + (at(x0 + 1, y0 + 1) - at(x0, y0 + 1)) * tx;
  return top + (bottom - top) * ty;
}

PlateBitmap RenderPlateBitmap(const MarkerPlateLayout& layout, double px_per_mm) {
  PlateBitmap bitmap;
  bitmap.px_per_mm = px_per_mm;
  bitmap.min_mm = layout.BoardMin();
  const Eigen::Vector2d size = layout.BoardMax() - layout.BoardMin();
  bitmap.width = static_cast<int>(std::lround(size.x() * px_per_mm));
  bitmap.height = static_cast<int>(std::lround(size.y() * px_per_mm));
  cv::Mat board(bitmap.height, bitmap.width, CV_8UC1, cv::Scalar(235));
  auto to_px = [&](const Eigen::Vector2d& p) {
    return cv::Point2d((p.x() - bitmap.min_mm.x()) * px_per_mm,
                       bitmap.height - (p.y() - bitmap.min_mm.y()) * px_per_mm);
  };
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(layout.aruco_dictionary);
  const int side_px = static_cast<int>(std::lround(layout.aruco_side_mm * px_per_mm));
  for (int id = 0; id < 4; ++id) {
    cv::Mat marker;
    cv::aruco::drawMarker(dictionary, id, side_px, marker, 1);
    // Printed black is not 0: keep some texture-free dynamic range.
    marker = marker * (225.0 / 255.0) + 10;
    const cv::Point2d centre = to_px(layout.aruco_centers_mm[id]);
    const int x0 = static_cast<int>(std::lround(centre.x - side_px / 2.0));
    const int y0 = static_cast<int>(std::lround(centre.y - side_px / 2.0));
    const cv::Rect roi(x0, y0, side_px, side_px);
    if ((roi & cv::Rect(0, 0, bitmap.width, bitmap.height)) == roi) marker.copyTo(board(roi));
  }
  for (const Eigen::Vector3d& m : layout.ViconMarkers())
    cv::circle(board, to_px(m.head<2>()), static_cast<int>(std::lround(9 * px_per_mm)),
               cv::Scalar(40), cv::FILLED, cv::LINE_AA);
  bitmap.pixels.assign(board.datastart, board.dataend);
  return bitmap;
}

}  // namespace lifmcr::synth
