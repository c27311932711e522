#pragma once
// The marker plate of the paper (supplementary, "Data Alignment"): four ArUco
// markers (OpenCV DICT_6X6_250, LiFCal's default dictionary 10, ids 0..3) and
// four Vicon markers at its corners. It defines the world frame: origin at the
// bottom-left Vicon marker, x along the table (to the right), y across it,
// z up; the printed surface is the plane z = 0.
// Layout, as the paper's pattern: id 2 bottom-left (the origin marker P_2),
// id 3 bottom-right (P_3, along +x), id 0 top-left (P_0, along +y), id 1
// top-right (P_1, the check point).

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace lifmcr::synth {

struct MarkerPlateLayout {
  double vicon_span_x_mm = 400;  // bottom-left -> bottom-right Vicon marker
  double vicon_span_y_mm = 280;  // bottom-left -> top-left Vicon marker
  double board_margin_mm = 25;   // board beyond the Vicon markers
  double aruco_side_mm = 100;    // black square side incl. its border bits
  int aruco_dictionary = 10;     // cv::aruco::DICT_6X6_250
  // Centres of ArUco ids 0..3 in the world (plate) frame, z = 0.
  std::array<Eigen::Vector2d, 4> aruco_centers_mm{
      Eigen::Vector2d(100, 200), Eigen::Vector2d(300, 200), Eigen::Vector2d(100, 80),
      Eigen::Vector2d(300, 80)};
  // The four Vicon markers (world frame), bottom-left first, counter-clockwise.
  std::array<Eigen::Vector3d, 4> ViconMarkers() const;
  Eigen::Vector2d BoardMin() const { return {-board_margin_mm, -board_margin_mm}; }
  Eigen::Vector2d BoardMax() const {
    return {vicon_span_x_mm + board_margin_mm, vicon_span_y_mm + board_margin_mm};
  }
};

// A grey bitmap of the printed board (white, black ArUco markers, small black
// discs under the Vicon markers) at `px_per_mm`; row 0 is the far (+y) edge.
struct PlateBitmap {
  int width = 0, height = 0;
  double px_per_mm = 0;
  Eigen::Vector2d min_mm;  // world (x, y) of the bottom-left board corner
  std::vector<std::uint8_t> pixels;
  // Bilinear reflectance in [0, 1] at world (x, y); nullopt-like -1 off the board.
  double Sample(double x_mm, double y_mm) const;
};

PlateBitmap RenderPlateBitmap(const MarkerPlateLayout& layout, double px_per_mm);

}  // namespace lifmcr::synth
