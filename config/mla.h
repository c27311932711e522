#pragma once
// The micro-lens array calibration of one camera, as Raytrix's RayCalibData
// 1.0 XML holds it (paper supplementary, "MLA Calibration File";
// replay/mla_xml.h reads it). Values are kept as the file states them; the
// one convention change (the file's y-up `offset` to image pixels) happens in
// ReferenceLensCenterPx and nowhere else.
//
// Lens types: the XML ids 0, 1, 2 are the paper's types 1, 2, 3. lifmcr uses
// the XML ids everywhere and prints "type id 0 (paper type 1)" where it helps.

#include <Eigen/Core>

#include <array>
#include <string>
#include <vector>

namespace lifmcr {

struct MlaLensType {
  int id = 0;                                             // XML id 0..2
  Eigen::Vector2d offset_lens = Eigen::Vector2d::Zero();  // relative to type id 0, lens diameters
  double depth_min = 0.0;                                 // sharp virtual-depth range
  double depth_max = 0.0;
};

struct MlaDistortion {
  std::string type = "radial";        // attribute of <distortion>
  std::string function = "constant";  // "constant" or "Brown"
  std::vector<double> parameters;     // <parameter count="N">p1;p2;...</parameter>
  Eigen::Vector2d offset_px = Eigen::Vector2d::Zero();  // distortion centre as written
};

struct MlaCalibration {
  std::string version = "1.0";
  Eigen::Vector2d offset_px =
      Eigen::Vector2d::Zero();  // image centre -> reference lens, x right, y UP
  double diameter_px = 0.0;     // micro-image diameter = lens pitch
  double rotation_rad = 0.0;    // any angle (one real file has pi/2)
  double lens_border_px = 1.0;
  double tcp_virtual_depth = 0.0;                       // total covering plane
  Eigen::Vector2d lens_base_x = Eigen::Vector2d(1, 0);  // lens diameters, signs as in the file
  Eigen::Vector2d lens_base_y = Eigen::Vector2d(0.5, 0.8660254037844386);
  Eigen::Vector2d sub_grid_base = Eigen::Vector2d(3, 1.7320508075688772);
  MlaDistortion distortion;
  std::array<MlaLensType, 3> lens_types{};

  // Centre of the reference micro lens in 0-based image pixels (x right,
  // y down) for an image of width x height: ((W-1)/2 + ox, (H-1)/2 - oy),
  // the same point as LiFCal's (W/2 - 0.5 + ox, H/2 - 0.5 - oy).
  Eigen::Vector2d ReferenceLensCenterPx(int width, int height) const;
};

}  // namespace lifmcr
