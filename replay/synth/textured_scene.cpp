// The textured table-top scene (`lifmcr synth --scene table`, scene.h).
//
// Scales (docs/synth.md, "Texture scales"): at the presets' viewing
// distances a raw pixel covers about 0.2 mm of the table, a micro image
// about 15 mm and the field of view 240 mm (small) to 650 mm (medium). The
// patterns therefore hold detail from about 0.3 mm (the finest grain) up to
// leaves and photo regions of tens of mm, and objects of 50 to 300 mm give
// depth layers 10 to 300 mm apart.

#include "replay/synth/patterns.h"
#include "replay/synth/scene.h"

#include <Eigen/Geometry>

#include <cmath>
#include <memory>
#include <random>

namespace lifmcr::synth {
namespace {

constexpr double kTableZ = -5.0;  // the table top (the plate's print is z = 0)

class SceneBuilder {
 public:
  SceneBuilder(Scene* scene, std::uint64_t seed)
      : scene_(scene), rng_(seed * 0xA0761D6478BD642FULL + 0x2545F4914F6CDD1DULL) {}

  double Uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  std::uint32_t Seed() { return static_cast<std::uint32_t>(rng_()); }
  Grain MakeGrain(double coarsest_mm, double amplitude) {
    Grain grain;
    grain.noise = NoiseTexture{coarsest_mm, 0.3, 0.7, Seed()};
    grain.amplitude = amplitude;
    return grain;
  }
  DeadLeavesParams Leaves(double min_mm, double max_mm, std::vector<Eigen::Vector3d> palette,
                          double spread) {
    DeadLeavesParams p;
    p.min_radius_mm = min_mm;
    p.max_radius_mm = max_mm;
    p.palette = std::move(palette);
    p.brightness_spread = spread;
    p.grain = MakeGrain(6.0, 0.45);
    p.seed = Seed();
    return p;
  }
  int AddDeadLeaves(double min_mm, double max_mm, std::vector<Eigen::Vector3d> palette,
                    double spread) {
    return Add(std::make_shared<DeadLeaves>(Leaves(min_mm, max_mm, std::move(palette), spread)));
  }
  int AddBanded(double feature_mm, int bands, std::vector<Eigen::Vector3d> palette) {
    BandedNoiseParams p;
    p.noise = NoiseTexture{feature_mm, 0.3, 0.62, Seed()};
    p.bands = bands;
    p.palette = std::move(palette);
    p.grain = MakeGrain(10.0, 0.4);
    return Add(std::make_shared<BandedNoise>(p));
  }
  int AddPrint(double block_mm, double photo_share, double glyph_mm, Eigen::Vector3d paper) {
    PrintedPageParams p;
    p.block_mm = block_mm;
    p.photo_share = photo_share;
    p.glyph_height_mm = glyph_mm;
    p.paper = paper;
    p.photo = Leaves(0.4, 0.4 * block_mm, PalettePhoto(), 0.6);
    p.grain = MakeGrain(10.0, 0.35);
    p.seed = Seed();
    return Add(std::make_shared<PrintedPage>(p));
  }
  int Add(std::shared_ptr<const SurfacePattern> pattern) {
    Material m;
    m.pattern = std::move(pattern);
    scene_->materials.push_back(m);
    return static_cast<int>(scene_->materials.size()) - 1;
  }
  // A box standing on `base_z` with its footprint centred at (x, y), jittered by the seed.
  void AddBox(double x, double y, double base_z, const Eigen::Vector3d& size, double yaw,
              int material, double jitter_mm = 15, double jitter_rad = 0.15) {
    const double cx = x + Uniform(-jitter_mm, jitter_mm), cy = y + Uniform(-jitter_mm, jitter_mm);
    const Eigen::Vector3d half(size.x() / 2, size.y() / 2, 0);
    scene_->boxes.push_back({Eigen::Vector3d(cx, cy, base_z) - half,
                             Eigen::Vector3d(cx, cy, base_z + size.z()) + half, material,
                             Box::Yawed(yaw + Uniform(-jitter_rad, jitter_rad))});
  }
  // Leaves of a plant: ellipses around `centre`, facing mostly up and out.
  void AddPlant(const Eigen::Vector3d& centre, double radius_mm, int leaves, int material) {
    QuadCluster plant;
    plant.centre_mm = centre;
    plant.radius_mm = radius_mm + 45;
    for (int k = 0; k < leaves; ++k) {
      Eigen::Vector3d offset;
      do {
        offset = Eigen::Vector3d(Uniform(-1, 1), Uniform(-1, 1), Uniform(-0.7, 1));
      } while (offset.squaredNorm() > 1.0);
      const Eigen::Vector3d at = centre + radius_mm * offset;
      // Leaf direction: outwards from the stem, rising; its normal tilted up.
      const double azimuth = std::atan2(offset.y(), offset.x()) + Uniform(-0.5, 0.5);
      const Eigen::Vector3d along =
          Eigen::Vector3d(std::cos(azimuth), std::sin(azimuth), Uniform(-0.2, 0.8)).normalized();
      Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(along);
      if (across.norm() < 1e-6) across = Eigen::Vector3d::UnitX();
      across.normalize();
      const double twist = Uniform(-0.6, 0.6);
      const Eigen::Vector3d v_axis =
          Eigen::AngleAxisd(twist, along).toRotationMatrix() * across;
      const double length = Uniform(40, 90), width = length * Uniform(0.35, 0.55);
      plant.quads.push_back({at, along, v_axis.normalized(), Eigen::Vector2d(-length / 2, -width / 2),
                             Eigen::Vector2d(length / 2, width / 2), material, true});
    }
    scene_->clusters.push_back(std::move(plant));
  }

 private:
  Scene* scene_;
  std::mt19937_64 rng_;
};

}  // namespace

Scene MakeTexturedTableScene(std::uint64_t seed) {
  Scene scene;
  scene.name = "table";
  SceneBuilder b(&scene, seed);
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ();
  const MarkerPlateLayout& plate = scene.plate;
  // Beyond the plate's centre, towards the objects behind it: at `medium`
  // every view of the default motions holds the whole plate and objects
  // around it; at `small` (a field of 240 mm) the middle of the plate, the
  // card and notebook on it and the cloth beyond.
  scene.target_mm = {plate.vicon_span_x_mm / 2, 210.0, 30.0};

  // Table cloth, wall, plate.
  const int cloth = b.AddDeadLeaves(2.0, 30, PaletteCloth(), 0.5);
  const int wall = b.AddBanded(90, 5, PaletteStone());
  scene.quads.push_back({Eigen::Vector3d(0, 0, kTableZ), x, y, {-1e12, -1e12}, {1e12, 1e12}, cloth});
  scene.quads.push_back({Eigen::Vector3d(0, 1400, 0), x, z, {-1e12, -1e12}, {1e12, 1e12}, wall});
  Material plate_material;
  plate_material.color_rgb = {0.95, 0.95, 0.95};
  plate_material.contrast = 0.0;
  plate_material.texture = NoiseTexture{5.0, 0.3, 0.72, b.Seed()};
  plate_material.plate = true;
  scene.materials.push_back(plate_material);
  const int plate_index = static_cast<int>(scene.materials.size()) - 1;
  scene.quads.push_back({Eigen::Vector3d::Zero(), x, y, plate.BoardMin(), plate.BoardMax(),
                         plate_index});
  scene.boxes.push_back({Eigen::Vector3d(plate.BoardMin().x(), plate.BoardMin().y(), kTableZ),
                         Eigen::Vector3d(plate.BoardMax().x(), plate.BoardMax().y(), -0.01),
                         plate_index});
  scene.plate_bitmap = std::make_shared<PlateBitmap>(RenderPlateBitmap(plate, 5.0));

  // On the plate's free middle strip (x 150..250 between the marker columns,
  // 10 mm clear of them): a photo card and a notebook.
  const double strip_x = 0.5 * (plate.aruco_centers_mm[0].x() + plate.aruco_centers_mm[1].x());
  const int photo = b.AddDeadLeaves(0.35, 25, PalettePhoto(), 0.6);
  scene.boxes.push_back({Eigen::Vector3d(strip_x - 40, 30, -0.01),
                         Eigen::Vector3d(strip_x + 40, 128, 1.0), photo});
  const int notebook = b.AddPrint(36, 0.3, 3.5, {0.9, 0.88, 0.8});
  scene.boxes.push_back({Eigen::Vector3d(strip_x - 38, 150, -0.01),
                         Eigen::Vector3d(strip_x + 38, 262, 12.0), notebook});

  // Behind the plate: a stack of books, a cereal box, a mug, a stone, a potted plant.
  const Eigen::Vector3d paper(0.93, 0.9, 0.83);
  double stack_z = kTableZ;
  for (int k = 0; k < 3; ++k) {
    const int book = b.AddPrint(55 + 15 * k, 0.5, 4.0 + k, paper);
    const Eigen::Vector3d size(220 - 20 * k, 150 - 10 * k, 28 + 6 * k);
    b.AddBox(110, 440, stack_z, size, 0.25 * (k - 1), book, 6, 0.1);
    stack_z += size.z();
  }
  const int cereal = b.AddPrint(70, 0.6, 7.0, {0.85, 0.75, 0.35});
  b.AddBox(-120, 500, kTableZ, {190, 70, 280}, 0.4, cereal);
  const int glaze = b.AddBanded(30, 7, PaletteCloth());
  const Eigen::Vector2d mug(310 + b.Uniform(-15, 15), 400 + b.Uniform(-15, 15));
  scene.cylinders.push_back({mug, 42, kTableZ, 95, glaze, glaze});
  const int stone = b.AddBanded(25, 8, PaletteStone());
  b.AddBox(260, 580, kTableZ, {120, 90, 60}, 0.7, stone);
  const int terracotta = b.AddBanded(20, 5, PaletteWood());
  const int soil = b.AddDeadLeaves(0.3, 6, PaletteWood(), 0.7);
  const Eigen::Vector2d pot(480 + b.Uniform(-15, 15), 470 + b.Uniform(-15, 15));
  scene.cylinders.push_back({pot, 70, kTableZ, 115, terracotta, soil});
  const int foliage = b.AddDeadLeaves(0.3, 10, PaletteFoliage(), 0.5);
  b.AddPlant(Eigen::Vector3d(pot.x(), pot.y(), 250), 130, 45, foliage);

  // Beside the plate: tools and a ruler on the left, a book and a box on the right.
  const int metal = b.AddBanded(15, 6, PaletteStone());
  const int handle = b.AddBanded(10, 4, PaletteCloth());
  b.AddBox(-150, 80, kTableZ, {170, 22, 18}, 0.5, handle);
  b.AddBox(-120, -30, kTableZ, {220, 12, 10}, -0.2, metal);
  const int ruler = b.AddPrint(25, 0.0, 3.0, {0.85, 0.8, 0.55});
  b.AddBox(-170, 200, kTableZ, {300, 32, 3}, -0.3, ruler);
  b.AddBox(-250, 330, kTableZ, {90, 90, 70}, 0.3, stone);
  const int book = b.AddPrint(60, 0.5, 5.0, paper);
  b.AddBox(590, 150, kTableZ, {210, 150, 30}, -0.4, book);
  const int box = b.AddPrint(50, 0.4, 4.0, {0.75, 0.85, 0.9});
  b.AddBox(570, -60, kTableZ, {110, 80, 90}, 0.2, box);

  // In front of the plate: a notebook.
  const int pad = b.AddPrint(45, 0.2, 3.5, paper);
  b.AddBox(200, -170, kTableZ, {200, 150, 8}, 0.1, pad);

  // A poster leaning against the back: slanted depth.
  const int poster = b.AddPrint(150, 0.8, 8.0, paper);
  const Eigen::Vector3d lean_v = Eigen::Vector3d(0, 0.5, 0.866);
  scene.quads.push_back(
      {Eigen::Vector3d(-150, 760, kTableZ), x, lean_v, {0, 0}, {700, 450}, poster});
  return scene;
}

}  // namespace lifmcr::synth
