#pragma once
// The micro-image lattice of one camera in image pixels, from the MLA file or
// fitted to a white image (docs/processing.md).
//
// Lattice: micro-image centre of lens (i, j) (axial hex coordinates)
//   c(i, j) = o + A (i, j)^T
// with o the reference lens centre and A the 2x2 matrix whose columns are the
// pixel steps of i and j. From a RayCalibData file (config/mla.h; y up,
// counter-clockwise rotation theta, pitch D, bases b_x, b_y in units of D):
//   A = F R(theta) D [b_x b_y],   F = diag(1, -1) (y up -> y down),
//   o = MlaCalibration::ReferenceLensCenterPx(W, H).
// Lens types (XML ids): type(i, j) = (sigma (i - j)) mod 3, with sigma = +1
// when the file's type-1 offset is +b_x (or -b_y), the colouring of the
// synthetic generator and LiFCal's `gridX mod 3`; sigma = -1 for the mirrored
// colouring. The reference lens is type 0.
//
// White-image fit: threshold each micro-image disc at half its plateau,
// take connected components for a first lattice (pitch = median nearest-
// neighbour distance, rotation from the neighbour directions modulo 60 deg),
// then per lens the centroid of (I - I_half)^+ within D/2 of the predicted
// centre (the disc is symmetric about c_k, so this is unbiased once the
// prediction is within the disc's margin), and a least-squares affine fit
// (o, A: pitch, rotation, aspect, shear) over all lenses, iterated.
// A white image alone cannot tell the lens types apart: with an MLA file the
// fit keeps its reference lens and colouring, without one the reference is
// the lens nearest the image centre and the type phase is unknown (reported).

#include "config/error.h"
#include "config/image.h"
#include "config/mla.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace lifmcr::processing {

int Mod3(int x);

struct MlaGrid {
  Eigen::Vector2d reference_px = Eigen::Vector2d::Zero();  // o, centre of lens (0, 0)
  Eigen::Matrix2d lattice = Eigen::Matrix2d::Identity();   // A, columns: steps of i, j (px)
  int type_sign = 1;                                       // sigma
  bool types_known = false;                                // false: fitted without an MLA file

  Eigen::Vector2d Center(int i, int j) const {
    return reference_px + lattice * Eigen::Vector2d(i, j);
  }
  int Type(int i, int j) const { return Mod3(type_sign * (i - j)); }
  // Lattice index of the micro image nearest to p (hex rounding).
  void Nearest(const Eigen::Vector2d& p_px, int* i, int* j) const;
  double PitchPx() const;      // mean length of the two lattice steps
  // PitchPx() rounded to 1e-6 px, for every choice that steps at a pitch
  // (search lattices, integer radii): an MLA file's base vectors, written to
  // 12 digits, put a 24 px pitch at 23.999999999995 px, and a comparison
  // with 24 would then choose as for a smaller lens.
  double NominalPitchPx() const;
  double RotationRad() const;  // of the i step, y up, counter-clockwise
  // Index range [i_min, i_max] x [j_min, j_max] covering a W x H image.
  void IndexBounds(int width, int height, int* i_min, int* i_max, int* j_min, int* j_max) const;

  static MlaGrid FromCalibration(const MlaCalibration& mla, int width, int height);
  // `base` with offset, diameter and rotation replaced by this lattice's.
  MlaCalibration ToCalibration(const MlaCalibration& base, int width, int height) const;
};

struct GridFitOptions {
  int iterations = 3;            // centroid / lattice-fit rounds
  double window_fraction = 0.5;  // centroid window radius / D
  double outlier_px = 0.5;       // centres farther than this from the fit are dropped
  Status Check() const;          // every field; the message names the field
};

struct GridFitResult {
  MlaGrid grid;
  int lenses = 0;     // centres used in the final fit
  int rejected = 0;   // centres dropped as outliers
  double rms_px = 0;  // residual of the centres about the fitted lattice
  double shear = 0;   // cos of the angle between the steps minus cos 60 deg
  double aspect = 1;  // |step j| / |step i|
  double seconds = 0;
  std::string BriefReport() const;  // one line
};

// Fits the lattice to a white image (Mono8 or BGR8). `initial` (may be null):
// the lattice of the MLA file, used as the start and for the lens types.
Expected<GridFitResult> FitGridToWhiteImage(ConstImageView white, const MlaGrid* initial,
                                            const GridFitOptions& options = {});

}  // namespace lifmcr::processing
