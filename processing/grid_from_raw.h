#pragma once
// The micro-image lattice from a raw image of a textured scene, for when no
// white image exists: the micro-image borders (the vignetting rim and the
// dark gaps between the discs) still show the lattice, but each disc holds
// scene texture, so a per-lens centroid (mla_grid.h's white-image fit) is
// biased by whatever the lens sees.
//
// Folded mean micro image: the image is cut into tiles of many lenses; in
// tile T, M_T(u) = median over its lenses k of I(c_k + u) / (a_k + g_k . u)
// (bilinear, u on the integer grid within D/2; a_k + g_k . u is the plane
// fitted to the lens's core, so neither the lens's brightness nor the
// scene's gradient across it, which would move a centroid, enters). Texture averages out over the
// tile's lenses, leaving the lenses' common vignetting profile, symmetric about the true centre. If
// the lattice puts the tile's centres off by delta_T, M_T is that profile shifted by delta_T, and
// the centroid of (M_T - max M_T / 2)^+ measures it. Since c = o + A (i, j) is linear, the mean
// displacement over the tile's lenses is that of its mean index (i_T, j_T), so the affine least
// squares of o + A (i_T, j_T) against the tiles' measured centres updates o and A (pitch, rotation,
// aspect, shear); iterated, as the fold sharpens when the lattice improves. The fold is the median
// over the lenses (strong texture in a few does not move it) and regions off the first fit by more
// than max(0.1 px, 3 x the median residual) are dropped before a second.

#include "config/error.h"
#include "config/image.h"
#include "processing/mla_grid.h"

namespace lifmcr::processing {

struct RawGridFitOptions {
  int iterations = 5;
  int min_lenses_per_tile = 60;  // tiles are made as small as this allows
  int max_tiles_per_side = 12;
  Status Check() const;
};

// `initial`: the lattice of the MLA file (kept: reference lens and lens
// types). Null: a first lattice from the white-image detector run on the
// raw (works when the texture leaves the discs brighter than the gaps; on a
// strongly textured scene it does not, and the fit says so). An error, not a
// lattice, when fewer than half of the regions agree with the fit or they
// hold less than a quarter of the micro images the image has room for.
// GridFitResult: rms_px of the regions' measured centres about the fitted
// lattice, `lenses` folded in the last round, `rejected` the lenses of the
// regions dropped.
Expected<GridFitResult> FitGridToRawImage(ConstImageView raw, const MlaGrid* initial,
                                          const RawGridFitOptions& options = {});

}  // namespace lifmcr::processing
