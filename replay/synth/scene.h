#pragma once
// Synthetic table-top scenes in the world (marker plate) frame: textured
// planes, rectangles, ellipses (leaves), boxes (turned about the vertical),
// vertical cylinders, and the marker plate. Radiance is Lambertian
// reflectance times a fixed light; the renderer asks for the colour of the
// first surface along a ray.
//
// Scenes (`lifmcr synth --scene`, MakeScene):
// - table (default): a table-top as real LiFMCR scenes are (plants, cards,
//   books, tools): a patterned cloth, the marker plate with a photo card and
//   a book on its free middle strip, books, boxes, a mug, tools and a potted
//   plant of a few dozen leaves around and behind it, a leaning poster and a
//   wall; every surface carries a natural-image-like pattern (patterns.h)
//   from a few micro-image pitches down to the pixel footprint, and the
//   objects stand at several depths and occlude each other and the plate's
//   edges (never the markers from the default viewpoints).
// - plain: the first synthetic scene: a wood-like table, a wall, the plate,
//   five boxes and a leaning board, each of one colour times fBm noise.

#include "config/error.h"
#include "replay/synth/marker_plate.h"
#include "replay/synth/patterns.h"
#include "replay/synth/texture.h"

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::synth {

struct Material {
  Eigen::Vector3d color_rgb{0.8, 0.8, 0.8};  // reflectance at texture value 1
  double contrast = 0.6;                     // 0: flat colour, 1: full texture range
  NoiseTexture texture;
  bool plate = false;  // reflectance from the marker-plate bitmap
  // When set, the colour reflectance (color_rgb, contrast and texture unused).
  std::shared_ptr<const SurfacePattern> pattern = nullptr;
};

// A rectangle (or, with infinite extents, a plane): origin + a u_axis + b v_axis.
struct Quad {
  Eigen::Vector3d origin, u_axis, v_axis;  // unit, orthogonal axes
  Eigen::Vector2d min_mm{-1e12, -1e12}, max_mm{1e12, 1e12};
  int material = 0;
  bool ellipse = false;  // only the ellipse inscribed in [min, max] (a leaf)
};

// The box [min, max] of the world frame turned about the vertical axis
// through its centre so that its own x axis points along `x_axis` (world x, y;
// unit): Yawed(yaw) for a yaw angle.
struct Box {
  Eigen::Vector3d min_mm, max_mm;
  int material = 0;
  Eigen::Vector2d x_axis = Eigen::Vector2d::UnitX();
  static Eigen::Vector2d Yawed(double yaw_rad) { return {std::cos(yaw_rad), std::sin(yaw_rad)}; }
};

// A vertical cylinder with a top cap (mug, can, plant pot).
struct Cylinder {
  Eigen::Vector2d centre_mm;
  double radius_mm = 10, z_min_mm = 0, z_max_mm = 10;
  int material = 0;      // side (u = arc length, v = height)
  int top_material = 0;  // cap (u, v = world x, y)
};

// Quads behind one bounding sphere (the leaves of a plant): rays that miss
// the sphere skip them all.
struct QuadCluster {
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();
  double radius_mm = 0;
  std::vector<Quad> quads;
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
  std::vector<Cylinder> cylinders;
  std::vector<QuadCluster> clusters;
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
  // The point the cameras look at (`target_mm`).
  Eigen::Vector3d Target() const { return target_mm; }
  Eigen::Vector3d target_mm{200, 140, 0};  // default: the centre of the default plate
};

// The scene called `name` (SceneNames()), placed from `seed`; an error names
// the choices.
Expected<Scene> MakeScene(std::string_view name, std::uint64_t seed);
std::string_view SceneNames();  // "table|plain"
// The textured table-top scene (`table`, the default), placed from `seed`.
Scene MakeTexturedTableScene(std::uint64_t seed);
// The plain table-top scene (`plain`): a table, a back wall, the marker
// plate, and a few boxes and a leaning board placed from `seed`, each of one
// colour times fBm noise.
Scene MakePlainScene(std::uint64_t seed);
// The plain scene under its first name, for callers written before --scene.
inline Scene MakeTableTopScene(std::uint64_t seed) { return MakePlainScene(seed); }
// A single textured infinite plane z = 0 (world), texture wavelengths from
// `feature_mm` down to the pixel footprint (for tests of depth and blur).
Scene MakePlaneScene(double feature_mm, std::uint32_t seed);
// Uniform radiance for white images.
Scene MakeWhiteScene();

}  // namespace lifmcr::synth
