#pragma once
// Synthetic table-top scenes in the world (marker plate) frame: textured
// planes, rectangles and boxes, and the marker plate. Radiance is Lambertian
// reflectance times a fixed light; the renderer asks for the colour of the
// first surface along a ray.

#include "replay/synth/marker_plate.h"
#include "replay/synth/texture.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::synth {

struct Material {
  Eigen::Vector3d color_rgb{0.8, 0.8, 0.8};  // reflectance at texture value 1
  double contrast = 0.6;                     // 0: flat colour, 1: full texture range
  NoiseTexture texture;
  bool plate = false;  // reflectance from the marker-plate bitmap
};

// A rectangle (or, with infinite extents, a plane): origin + a u_axis + b v_axis.
struct Quad {
  Eigen::Vector3d origin, u_axis, v_axis;  // unit, orthogonal axes
  Eigen::Vector2d min_mm{-1e12, -1e12}, max_mm{1e12, 1e12};
  int material = 0;
};

// An axis-aligned box in the world frame.
struct Box {
  Eigen::Vector3d min_mm, max_mm;
  int material = 0;
};

struct Hit {
  double t = 0;            // ray parameter (direction as given)
  Eigen::Vector3d point;   // world, mm
  Eigen::Vector3d normal;  // world, unit, facing the ray
  Eigen::Vector2d uv_mm;   // surface coordinates for the texture
  int material = 0;
};

class Scene {
 public:
  std::string name;
  std::vector<Material> materials;
  std::vector<Quad> quads;
  std::vector<Box> boxes;
  MarkerPlateLayout plate;
  std::shared_ptr<const PlateBitmap> plate_bitmap;  // set when a material has plate = true
  Eigen::Vector3d light_dir{0.3, -0.4, 0.87};       // towards the light, world
  double ambient = 0.45;
  bool uniform_white = false;  // white-image scene: radiance 1 everywhere

  // First hit with t > 0 along origin + t dir (world frame).
  std::optional<Hit> Intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const;
  // Radiance (linear RGB, 1 = white lit head-on) of a hit seen with a sample
  // footprint of `footprint_mm`.
  Eigen::Vector3d Shade(const Hit& hit, double footprint_mm) const;
  // An id that changes exactly where the reflectance steps (material
  // boundaries, the edges of black marker cells), so that ground truth can
  // tell textured surfaces from step edges.
  int Region(const Hit& hit) const;
  // A point the cameras look at (centre of the plate).
  Eigen::Vector3d Target() const;
};

// The default table-top scene: a table, a back wall, the marker plate, and a
// few textured boxes and a leaning board placed from `seed`.
Scene MakeTableTopScene(std::uint64_t seed);
// A single textured infinite plane z = 0 (world), texture wavelengths from
// `feature_mm` down to the pixel footprint (for tests of depth and blur).
Scene MakePlaneScene(double feature_mm, std::uint32_t seed);
// Uniform radiance for white images.
Scene MakeWhiteScene();

}  // namespace lifmcr::synth
