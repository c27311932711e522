#include "replay/synth/scene.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace lifmcr::synth {
namespace {

constexpr double kEpsilon = 1e-9;

}  // namespace

namespace {

// Ray against one quad; updates `best` when nearer.
bool IntersectQuad(const Quad& q, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                   Hit* best) {
  const Eigen::Vector3d n = q.u_axis.cross(q.v_axis);
  const double denom = n.dot(dir);
  if (std::abs(denom) < kEpsilon) return false;
  const double t = n.dot(q.origin - origin) / denom;
  if (t <= kEpsilon || t >= best->t) return false;
  const Eigen::Vector3d p = origin + t * dir;
  const Eigen::Vector3d d = p - q.origin;
  const Eigen::Vector2d uv(d.dot(q.u_axis), d.dot(q.v_axis));
  if (uv.x() < q.min_mm.x() || uv.y() < q.min_mm.y() || uv.x() > q.max_mm.x() ||
      uv.y() > q.max_mm.y())
    return false;
  if (q.ellipse) {
    const Eigen::Vector2d half = 0.5 * (q.max_mm - q.min_mm);
    const Eigen::Vector2d e = (uv - 0.5 * (q.max_mm + q.min_mm)).cwiseQuotient(half);
    if (e.squaredNorm() > 1.0) return false;
  }
  *best = {t, p, denom < 0 ? n : Eigen::Vector3d(-n), uv, q.material};
  return true;
}

// Ray against a box given in its own frame (axis-aligned there).
bool IntersectAlignedBox(const Eigen::Vector3d& min_mm, const Eigen::Vector3d& max_mm,
                         int material, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                         Hit* best) {
  // Slab method; remember which slab gave the entry.
  double t_near = -std::numeric_limits<double>::infinity();
  double t_far = std::numeric_limits<double>::infinity();
  int axis_near = 0;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(dir[a]) < kEpsilon) {
      if (origin[a] < min_mm[a] || origin[a] > max_mm[a]) return false;
      continue;
    }
    double t0 = (min_mm[a] - origin[a]) / dir[a];
    double t1 = (max_mm[a] - origin[a]) / dir[a];
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > t_near) {
      t_near = t0;
      axis_near = a;
    }
    t_far = std::min(t_far, t1);
  }
  if (t_near > t_far || t_near <= kEpsilon || t_near >= best->t) return false;
  const Eigen::Vector3d p = origin + t_near * dir;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  n[axis_near] = dir[axis_near] > 0 ? -1.0 : 1.0;
  // Texture coordinates: the two axes of the face.
  const int u_axis = axis_near == 0 ? 1 : 0;
  const int v_axis = axis_near == 2 ? 1 : 2;
  *best = {t_near, p, n, Eigen::Vector2d(p[u_axis], p[v_axis]), material};
  return true;
}

// Whether the ray meets the sphere before `t_max`.
bool MeetsSphere(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& origin,
                 const Eigen::Vector3d& dir, double t_max) {
  const Eigen::Vector3d oc = origin - centre;
  const double a = dir.squaredNorm(), half_b = oc.dot(dir), c = oc.squaredNorm() - radius * radius;
  const double disc = half_b * half_b - a * c;
  if (disc < 0) return false;
  const double root = std::sqrt(disc);
  return (-half_b + root) / a > kEpsilon && (-half_b - root) / a < t_max;
}

bool IntersectBox(const Box& b, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                  Hit* best) {
  // Most rays miss most boxes: a bounding sphere rejects them without divisions.
  if (!MeetsSphere(0.5 * (b.min_mm + b.max_mm), 0.5 * (b.max_mm - b.min_mm).norm(), origin, dir,
                   best->t))
    return false;
  if (b.x_axis.x() == 1.0) return IntersectAlignedBox(b.min_mm, b.max_mm, b.material, origin, dir, best);
  // Into the box frame: centred, turned back.
  const Eigen::Vector3d centre = 0.5 * (b.min_mm + b.max_mm);
  const Eigen::Vector2d xa = b.x_axis, ya(-xa.y(), xa.x());
  const auto to_box = [&](const Eigen::Vector3d& w) {
    return Eigen::Vector3d(xa.dot(w.head<2>()), ya.dot(w.head<2>()), w.z());
  };
  Hit local = *best;
  if (!IntersectAlignedBox(b.min_mm - centre, b.max_mm - centre, b.material,
                           to_box(origin - centre), to_box(dir), &local))
    return false;
  local.point = origin + local.t * dir;
  const Eigen::Vector2d n = local.normal.x() * xa + local.normal.y() * ya;
  local.normal = Eigen::Vector3d(n.x(), n.y(), local.normal.z());
  *best = local;
  return true;
}

bool IntersectCylinder(const Cylinder& c, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& dir, Hit* best) {
  bool found = false;
  const Eigen::Vector2d o = origin.head<2>() - c.centre_mm, d = dir.head<2>();
  const double r2 = c.radius_mm * c.radius_mm;
  // Side: |o + t d|^2 = r^2, the nearer root from outside.
  const double a = d.squaredNorm();
  if (a > kEpsilon) {
    const double half_b = o.dot(d), cc = o.squaredNorm() - r2;
    const double disc = half_b * half_b - a * cc;
    if (disc >= 0) {
      const double t = (-half_b - std::sqrt(disc)) / a;
      const double z = origin.z() + t * dir.z();
      if (t > kEpsilon && t < best->t && z >= c.z_min_mm && z <= c.z_max_mm) {
        const Eigen::Vector2d radial = (o + t * d) / c.radius_mm;
        const double angle = std::atan2(radial.y(), radial.x());
        *best = {t, origin + t * dir, Eigen::Vector3d(radial.x(), radial.y(), 0),
                 Eigen::Vector2d(angle * c.radius_mm, z), c.material};
        found = true;
      }
    }
  }
  // Top cap.
  if (std::abs(dir.z()) > kEpsilon) {
    const double t = (c.z_max_mm - origin.z()) / dir.z();
    if (t > kEpsilon && t < best->t && (o + t * d).squaredNorm() <= r2) {
      const Eigen::Vector3d p = origin + t * dir;
      *best = {t, p, Eigen::Vector3d(0, 0, dir.z() < 0 ? 1.0 : -1.0), p.head<2>(),
               c.top_material};
      found = true;
    }
  }
  return found;
}

}  // namespace

std::optional<Hit> Scene::Intersect(const Eigen::Vector3d& origin,
                                    const Eigen::Vector3d& dir) const {
  Hit best;
  best.t = std::numeric_limits<double>::infinity();
  bool found = false;
  for (const Quad& q : quads) found |= IntersectQuad(q, origin, dir, &best);
  for (const Box& b : boxes) found |= IntersectBox(b, origin, dir, &best);
  for (const Cylinder& c : cylinders) found |= IntersectCylinder(c, origin, dir, &best);
  for (const QuadCluster& cluster : clusters) {
    if (!MeetsSphere(cluster.centre_mm, cluster.radius_mm, origin, dir, best.t)) continue;
    for (const Quad& q : cluster.quads) found |= IntersectQuad(q, origin, dir, &best);
  }
  if (!found) return std::nullopt;
  return best;
}

Eigen::Vector3d Scene::Shade(const Hit& hit, double footprint_mm) const {
  if (uniform_white) return Eigen::Vector3d::Ones();
  const Material& m = materials[hit.material];
  double reflectance = 0.0;
  if (m.plate && plate_bitmap) {
    const double r = plate_bitmap->Sample(hit.point.x(), hit.point.y());
    reflectance = r < 0 ? 0.5 : r;
    // Fine paper grain so that stereo also works on the white board.
    reflectance *= 0.93 + 0.07 * m.texture.Sample(hit.uv_mm.x(), hit.uv_mm.y(), footprint_mm);
  } else if (m.pattern) {
    const double lambert = std::max(0.0, hit.normal.dot(light_dir.normalized()));
    const double light = ambient + (1.0 - ambient) * lambert;
    return m.pattern->Reflectance(hit.uv_mm.x(), hit.uv_mm.y(), footprint_mm) * light;
  } else {
    const double t = m.texture.Sample(hit.uv_mm.x(), hit.uv_mm.y(), footprint_mm);
    reflectance = 1.0 - m.contrast + m.contrast * t;
  }
  const double lambert = std::max(0.0, hit.normal.dot(light_dir.normalized()));
  const double light = ambient + (1.0 - ambient) * lambert;
  return m.color_rgb * (reflectance * light);
}

int Scene::Region(const Hit& hit) const {
  int plate_class = 0;
  if (materials[hit.material].plate && plate_bitmap) {
    const double r = plate_bitmap->Sample(hit.point.x(), hit.point.y());
    plate_class = r < 0 ? 0 : (r >= 0.5 ? 1 : 2);
  }
  return 3 * hit.material + plate_class;
}

Scene MakePlainScene(std::uint64_t seed) {
  Scene scene;
  scene.name = "plain";
  scene.target_mm = {scene.plate.vicon_span_x_mm / 2, scene.plate.vicon_span_y_mm / 2, 0.0};
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ULL + 17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto texture = [&](double feature_mm) {
    NoiseTexture t;
    t.feature_mm = feature_mm;
    t.seed = static_cast<std::uint32_t>(rng());
    return t;
  };
  // 0: table (wood-like brown), 1: wall (grey-blue), 2: plate, 3..: boxes.
  scene.materials.push_back({{0.75, 0.55, 0.35}, 0.55, texture(60), false});
  scene.materials.push_back({{0.65, 0.7, 0.8}, 0.6, texture(120), false});
  scene.materials.push_back({{0.95, 0.95, 0.95}, 0.0, texture(5), true});
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ();
  constexpr double kPlateThicknessMm = 5.0;
  scene.quads.push_back(
      {Eigen::Vector3d(0, 0, -kPlateThicknessMm), x, y, {-1e12, -1e12}, {1e12, 1e12}, 0});
  scene.quads.push_back({Eigen::Vector3d(0, 1400, 0), x, z, {-1e12, -1e12}, {1e12, 1e12}, 1});
  scene.quads.push_back(
      {Eigen::Vector3d::Zero(), x, y, scene.plate.BoardMin(), scene.plate.BoardMax(), 2});
  // The plate's edges, so that a grazing view sees a board, not a floating sheet.
  scene.boxes.push_back(
      {Eigen::Vector3d(scene.plate.BoardMin().x(), scene.plate.BoardMin().y(), -kPlateThicknessMm),
       Eigen::Vector3d(scene.plate.BoardMax().x(), scene.plate.BoardMax().y(), -0.01), 2});
  scene.plate_bitmap = std::make_shared<PlateBitmap>(RenderPlateBitmap(scene.plate, 5.0));
  // Boxes around and behind the plate, never on it.
  const std::array<Eigen::Vector2d, 5> slots{Eigen::Vector2d(-260, 120), Eigen::Vector2d(560, 60),
                                             Eigen::Vector2d(60, 480), Eigen::Vector2d(330, 520),
                                             Eigen::Vector2d(620, 420)};
  for (const Eigen::Vector2d& slot : slots) {
    const Eigen::Vector3d color(0.35 + 0.6 * unit(rng), 0.35 + 0.6 * unit(rng),
                                0.35 + 0.6 * unit(rng));
    scene.materials.push_back({color, 0.7, texture(10 + 40 * unit(rng)), false});
    const Eigen::Vector3d size(80 + 120 * unit(rng), 80 + 120 * unit(rng), 60 + 180 * unit(rng));
    const Eigen::Vector3d centre(slot.x() + 40 * (unit(rng) - 0.5),
                                 slot.y() + 40 * (unit(rng) - 0.5), 0);
    scene.boxes.push_back(
        {Eigen::Vector3d(centre.x() - size.x() / 2, centre.y() - size.y() / 2, -kPlateThicknessMm),
         Eigen::Vector3d(centre.x() + size.x() / 2, centre.y() + size.y() / 2,
                         size.z() - kPlateThicknessMm),
         static_cast<int>(scene.materials.size()) - 1});
  }
  // A board leaning against the wall side: slanted depth for the depth stage.
  scene.materials.push_back({{0.85, 0.8, 0.6}, 0.75, texture(25), false});
  const Eigen::Vector3d lean_v = Eigen::Vector3d(0, 0.5, 0.866);
  scene.quads.push_back({Eigen::Vector3d(-150, 760, -kPlateThicknessMm),
                         x,
                         lean_v,
                         {0, 0},
                         {700, 450},
                         static_cast<int>(scene.materials.size()) - 1});
  return scene;
}

Scene MakePlaneScene(double feature_mm, std::uint32_t seed) {
  Scene scene;
  scene.name = "plane";
  NoiseTexture t;
  t.feature_mm = feature_mm;
  t.seed = seed;
  scene.materials.push_back({{0.9, 0.9, 0.9}, 0.8, t, false});
  scene.quads.push_back({Eigen::Vector3d::Zero(),
                         Eigen::Vector3d::UnitX(),
                         Eigen::Vector3d::UnitY(),
                         {-1e12, -1e12},
                         {1e12, 1e12},
                         0});
  scene.light_dir = Eigen::Vector3d::UnitZ();
  scene.ambient = 1.0;
  return scene;
}

std::string_view SceneNames() { return "table|plain"; }

Expected<Scene> MakeScene(std::string_view name, std::uint64_t seed) {
  if (name == "table") return MakeTexturedTableScene(seed);
  if (name == "plain") return MakePlainScene(seed);
  return Error{"unknown scene '" + std::string(name) + "', expected " + std::string(SceneNames())};
}

Scene MakeWhiteScene() {
  Scene scene;
  scene.name = "white";
  scene.uniform_white = true;
  return scene;
}

}  // namespace lifmcr::synth
