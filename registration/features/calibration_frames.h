#pragma once
// What calibration needs of one raw frame, made by the processing library:
// devignetting, virtual depth, the TF depth map and the TF image (with the
// micro-lens centres of the initial intrinsics), SIFT on the TF image with
// the measured virtual depth and colour of each keypoint, and the ArUco
// plate corners (found on the TF image, placed on the plate rendered again
// at its plane's virtual depth: plate_plane.h; each corner's virtual depth
// the measured one). The raw frame, white image and MLA file are read through
// replay/ (the LiFMCR layout).

#include "config/error.h"
#include "config/mla.h"
#include "processing/plenoptic_frame.h"
#include "registration/features/aruco_plate.h"
#include "registration/features/features.h"
#include "registration/features/keypoint_depth.h"
#include "registration/features/plate_plane.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct CalibrationFrame {
  std::int64_t frame = 0;
  std::string name;  // raw file name
  int tf_width = 0, tf_height = 0;
  Features features;                              // on the TF grid
  std::vector<float> virtual_depth;               // per keypoint, NaN where the map is empty
  // Per keypoint: the relative range of the virtual depth over its support
  // (keypoint_depth.h), NaN where the map is mostly empty there.
  std::vector<float> virtual_depth_range;
  std::vector<std::array<std::uint8_t, 3>> rgb;   // per keypoint (TF colour)
  std::vector<PlateCorner> corners;               // ArUco plate corners seen
  std::vector<float> corner_virtual_depth;        // per corner, NaN where the map is empty
  double tf_depth_coverage = 0;                   // share of TF pixels with a virtual depth
  double seconds = 0;                             // processing time of the frame
};

// The micro images of the camera: centres c_k and the lattice to find the
// lenses that see a virtual point.
struct MicroImages {
  processing::MlaGrid grid;
  std::vector<Eigen::Vector2d> centres_px;  // c_k
  std::vector<std::int32_t> index;          // (j - j_min) * ni + (i - i_min) -> k, or -1
  int i_min = 0, j_min = 0, ni = 0, nj = 0;
  double radius_px = 0;  // r_valid
  // Micro images whose disc holds p_k = l_k + (x_v - l_k) / v (lambda as given).
  void Seeing(const Eigen::Vector2d& virtual_px, double v, const Eigen::Vector2d& c,
              double lambda, std::vector<int>* lenses) const;
};

struct FrameLoaderOptions {
  double lambda = 1.0;  // b_L0 / (b_L0 + B) of the initial intrinsics
  std::optional<Eigen::Vector2d> principal_point_px;  // c of l_k (initial intrinsics); unset: centre
  FeatureOptions features;
  KeypointDepthSupport keypoint_support;  // of CalibrationFrame::virtual_depth_range
  Status Check() const;
};

// A processed frame on disk (a cache for repeated calibrations of the same
// frames processed the same way): binary, little-endian, magic "LFMCRFRM",
// version 6, what the frame was processed with (lambda; the principal point
// of l_k, NaN NaN for the image centre; the SIFT keypoint limit; the radius
// of a keypoint's depth support), then the fields of CalibrationFrame in
// order. Reading gives an error when the file
// is not one, or was processed with other options (other initial intrinsics:
// its virtual depths and TF image belong to other micro-lens centres).
Status SaveCalibrationFrame(const std::filesystem::path& path, const CalibrationFrame& frame,
                            const FrameLoaderOptions& processed_with);
Expected<CalibrationFrame> LoadCalibrationFrame(const std::filesystem::path& path,
                                                const FrameLoaderOptions& processed_with);

class CalibrationFrameLoader {
 public:
  // Reads the white image and the MLA file once (`mla_path` empty: the
  // dataset's Calibration/02_MLA_Calibration file).
  static Expected<std::unique_ptr<CalibrationFrameLoader>> Open(
      const std::filesystem::path& sequence_dir, const std::string& serial,
      const std::filesystem::path& mla_path, const PlateLayout& plate,
      const FrameLoaderOptions& options);
  ~CalibrationFrameLoader();
  // Frames present in the camera folder, ascending.
  const std::vector<std::int64_t>& frames() const { return frames_; }
  const MicroImages& micro_images() const { return micro_; }
  int width() const { return width_; }
  int height() const { return height_; }
  Expected<CalibrationFrame> Load(std::int64_t frame);
  // The TF image of the last frame Load processed (valid until the next Load).
  ConstImageView last_tf_image() const;
  // The TF depth map of the last frame Load processed (valid until the next Load).
  const std::vector<float>& last_tf_virtual_depth() const;
  // The corners of `markers` (quads on the TF grid: where to start the edge
  // fits) placed again on frame `frame`'s plate rendered at the virtual
  // depth `plane` over each marker's quad scaled by
  // PlatePlaneOptions::region_scale (the rest of the TF image at the plane's
  // depth at the markers' mean centre: no corner reads it). The raw frame is
  // read and rendered again; no virtual depth is estimated (a fraction of
  // Load's time). For a plane not taken from the measured depths: one
  // predicted by a calibration from the plate's own geometry
  // (registration/calibration/plate_plane_model.h).
  Expected<std::vector<PlateCorner>> PlaceCornersAtPlane(std::int64_t frame,
                                                         const std::vector<PlateMarker>& markers,
                                                         const PlatePlane& plane,
                                                         const MarkerEdgeOptions& edges);

 private:
  CalibrationFrameLoader() = default;
  struct State;
  std::unique_ptr<State> state_;
  std::vector<std::int64_t> frames_;
  MicroImages micro_;
  int width_ = 0, height_ = 0;
};

}  // namespace lifmcr::registration
