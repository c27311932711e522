#pragma once
// The marker plate's virtual depth as the plane it is, for rendering the
// plate's TF image in focus before its corners are placed.
//
// Why: the TF image renders each pixel at the measured virtual depth under
// it, and a TF pixel rendered at a wrong depth v' of a point at v_t is
// blended from micro images that each put it (1 - v' / v_t)(x - l_k) away
// (processing/tf_kernel.h): where the measured depth scatters along a
// marker's black/white border (it does most there), the border is drawn
// shifted and blurred, and the line fits of marker_edges.h move with it.
// The plate is a plane, and the virtual image of a plane through the thin
// lens is a plane: with TF coordinates (u, w) and x_v = 2 u + 1/2,
//   v(u, w) = a + b u + c w
// exactly (TF positions are lateral virtual-image coordinates, v is affine
// in the image distance). It is fitted to the measured depths inside the
// markers (their code cells are texture), robustly: least squares, then
// the samples within `reject_sigmas` robust standard deviations (1.4826 x
// the median absolute residual, relative to v) of the fit, refitted.

#include "config/error.h"
#include "registration/features/aruco_plate.h"

#include <vector>

namespace lifmcr::registration {

struct PlatePlane {
  double a = 0, b = 0, c = 0;  // v = a + b u + c w on the TF grid
  int samples = 0;             // measured pixels the last fit kept
  double rms_rel = 0;          // their residuals' RMS relative to v
  double At(double u, double w) const { return a + b * u + c * w; }
};

struct PlatePlaneOptions {
  int min_samples = 100;       // measured pixels inside the markers a fit needs
  double reject_sigmas = 3.0;  // robust standard deviations a kept sample lies within
  int iterations = 5;          // refits
  // The region written by WritePlatePlaneDepth: each marker's quad scaled
  // about its centre by this factor (1.5: a quarter of its side of the
  // white surround on each side, beyond the edge profiles' reach).
  double region_scale = 1.5;
  Status Check() const;
};

// The plane through the measured virtual depths `v` (a TF grid of width x
// height, NaN where empty) inside `markers`' quads; where `sigma_z` has the
// grid's size, only its finite pixels count as measured (TfDepthMap's
// filled pixels are NaN there), else every finite `v`. An error when fewer
// than min_samples pixels are measured or the fit is not a depth (v <= 1
// at a marker's centre).
Expected<PlatePlane> FitPlatePlane(const std::vector<float>& v, const std::vector<float>& sigma_z,
                                   int width, int height, const std::vector<PlateMarker>& markers,
                                   const PlatePlaneOptions& options);

// Writes the plane's depth into `v` (a TF grid of width x height) at every
// pixel of the markers' scaled quads (options.region_scale).
void WritePlatePlaneDepth(const PlatePlane& plane, const std::vector<PlateMarker>& markers,
                          const PlatePlaneOptions& options, int width, int height,
                          std::vector<float>* v);

}  // namespace lifmcr::registration
