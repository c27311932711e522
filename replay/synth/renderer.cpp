#include "replay/synth/renderer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace lifmcr::synth {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Counter-based random numbers: splitmix64 of (seed, index).
std::uint64_t SplitMix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Near-normal deviate (zero mean, unit variance) from the hash of (seed,
// index): the sum of four 16-bit uniforms (Irwin-Hall), which is within 1 %
// of a Gaussian inside +-2.5 sigma and needs no transcendental functions.
double Gaussian(std::uint64_t seed, std::uint64_t index) {
  const std::uint64_t h = SplitMix(seed ^ SplitMix(index));
  const double sum = static_cast<double>(h & 0xFFFF) + static_cast<double>((h >> 16) & 0xFFFF) +
                     static_cast<double>((h >> 32) & 0xFFFF) + static_cast<double>(h >> 48);
  return (sum / 65536.0 - 2.0) * 1.7320508075688772;
}

struct TraceResult {
  bool hit = false;
  Eigen::Vector3d radiance = Eigen::Vector3d::Zero();
  double depth_mm = 0;
};

// First surface along the object-side locus of an image-side line. Without
// distortion the locus is the straight `ray`; with it, iterate on the depth
// (plenoptic_model.h, ObjectRayOfImagePoint).
template <typename LineAt>
std::optional<Hit> IntersectLocus(const PlenopticModel& model, const Scene& scene,
                                  const Pose& world_from_cam, const Pose& cam_from_world,
                                  const Ray& ray, LineAt line_at, Eigen::Vector3d* p_in_cam,
                                  const ObjectSubset* subset = nullptr) {
  const Eigen::Matrix3d rotation = world_from_cam.linear();
  std::optional<Hit> hit =
      scene.Intersect(world_from_cam * ray.origin, rotation * ray.direction, subset);
  if (!hit) return std::nullopt;
  *p_in_cam = cam_from_world * hit->point;
  if (!model.has_distortion()) return hit;
  for (int iteration = 0; iteration < 4 && p_in_cam->z() > model.params().main_focal_length_mm;
       ++iteration) {
    const Ray r = model.ObjectRayOfImagePoint(line_at(model.ImageDistanceOfDepth(p_in_cam->z())));
    std::optional<Hit> next = scene.Intersect(world_from_cam * r.origin, rotation * r.direction);
    if (!next) return std::nullopt;
    hit = next;
    *p_in_cam = cam_from_world * hit->point;
  }
  return hit;
}

// The objects the rays of micro image `lens` may meet. Every object-side ray
// of a pixel behind lens k runs from -M on the main lens (|M| within the
// aperture) towards Q / f_L (plenoptic_model.h), and for the line through
// the micro-lens centre L = (x, y, b) that ray passes through L's conjugate
// z_o = f_L b / (b - f_L), (x, y) z_o / b: a cone with that apex through the
// aperture disc (widened by 30 % for the rim's blur, and the angle by 50 %).
// False when no such cone exists (distortion bends the rays; b = f_L).
bool ObjectsOfMicroImage(const PlenopticModel& model, const Scene& scene,
                         const Pose& world_from_cam, const MicroLens& lens, ObjectSubset* out) {
  if (model.has_distortion()) return false;
  const double f = model.params().main_focal_length_mm, b = lens.lens_mm.z();
  if (std::abs(b - f) < 1e-6 * f) return false;
  const double z_o = f * b / (b - f);
  const Eigen::Vector3d apex(lens.lens_mm.x() * z_o / b, lens.lens_mm.y() * z_o / b, z_o);
  const double distance = apex.norm();
  const double aperture_radius = 0.65 * model.aperture_mm();
  if (distance < 4 * aperture_radius) return false;
  const double half_angle = 1.5 * std::asin(aperture_radius / distance);
  scene.ObjectsInCone(world_from_cam * apex, world_from_cam.linear() * (-apex / distance),
                      half_angle, out);
  return true;
}

// Gaussian kernels for sigma in steps of 1/kSigmaSteps px, radius 2.5 sigma.
constexpr int kSigmaSteps = 20;
struct KernelTable {
  explicit KernelTable(double max_sigma) {
    const int count = static_cast<int>(std::ceil(max_sigma * kSigmaSteps)) + 2;
    for (int k = 0; k < count; ++k) {
      const double s = std::max(k, 1) / static_cast<double>(kSigmaSteps);
      const int radius = static_cast<int>(std::ceil(2.5 * s));
      std::vector<float> weights(2 * radius + 1);
      for (int d = -radius; d <= radius; ++d)
        weights[d + radius] = static_cast<float>(std::exp(-0.5 * d * d / (s * s)));
      kernels.push_back(std::move(weights));
    }
  }
  const std::vector<float>& For(float sigma) const {
    const auto k = static_cast<std::size_t>(std::lround(sigma * kSigmaSteps));
    return kernels[std::min(k, kernels.size() - 1)];
  }
  std::vector<std::vector<float>> kernels;
};

// Separable Gaussian with a per-pixel sigma over the masked pixels of one tile.
void BlurTile(int w, int h, const std::vector<std::uint8_t>& mask, const std::vector<float>& sigma,
              const KernelTable& kernels, std::vector<Eigen::Vector3f>* tile) {
  std::vector<Eigen::Vector3f> pass(tile->size());
  for (int direction = 0; direction < 2; ++direction) {
    const std::vector<Eigen::Vector3f>& in = *tile;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int idx = y * w + x;
        if (!mask[idx]) {
          pass[idx] = in[idx];
          continue;
        }
        const float s = sigma[idx];
        if (s < 0.3f) {
          pass[idx] = in[idx];
          continue;
        }
        const std::vector<float>& kernel = kernels.For(s);
        const int radius = static_cast<int>(kernel.size() / 2);
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        float weight = 0.0f;
        for (int d = -radius; d <= radius; ++d) {
          const int qx = direction == 0 ? x + d : x, qy = direction == 0 ? y : y + d;
          if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
          const int q = qy * w + qx;
          if (!mask[q]) continue;
          const float g = kernel[d + radius];
          sum += g * in[q];
          weight += g;
        }
        pass[idx] = sum / weight;
      }
    tile->swap(pass);
  }
}

}  // namespace

ConstImageView RawFrame::View() const {
  return {pixels.data(), width, height, static_cast<std::size_t>(width) * BytesPerPixel(format),
          format};
}

ConstImageView TfGroundTruth::View() const {
  return {bgr.data(), width, height, static_cast<std::size_t>(width) * 3, PixelFormat::kBgr8};
}

RawFrame RenderRaw(const PlenopticModel& model, const Scene& scene, const Pose& world_from_cam,
                   const RenderOptions& options) {
  const SynthCameraParams& cam = model.params();
  RawFrame frame;
  frame.width = model.width();
  frame.height = model.height();
  frame.format = cam.bayer ? PixelFormat::kMono8 : PixelFormat::kBgr8;
  const int bpp = BytesPerPixel(frame.format);
  frame.pixels.assign(static_cast<std::size_t>(frame.width) * frame.height * bpp, 0);
  frame.virtual_depth.assign(static_cast<std::size_t>(frame.width) * frame.height, kNaN);

  // Lattice rows/columns that can own an image pixel: invert the corners.
  const double pitch = cam.micro_image_pitch_px;
  const int reach = static_cast<int>(std::ceil(0.6 * pitch)) + 1;
  int i_min = 1 << 30, i_max = -(1 << 30), j_min = 1 << 30, j_max = -(1 << 30);
  for (const Eigen::Vector2d& corner :
       {Eigen::Vector2d(-pitch, -pitch), Eigen::Vector2d(frame.width + pitch, -pitch),
        Eigen::Vector2d(-pitch, frame.height + pitch),
        Eigen::Vector2d(frame.width + pitch, frame.height + pitch)}) {
    int i = 0, j = 0;
    model.NearestLens(corner, &i, &j);
    i_min = std::min(i_min, i);
    i_max = std::max(i_max, i);
    j_min = std::min(j_min, j);
    j_max = std::max(j_max, j);
  }
  // The lattice is sheared (i + j/2): widen i by the j extent.
  const int shear = (j_max - j_min) / 2 + 2;
  i_min -= shear;
  i_max += shear;

  const double b_l0 = cam.mla_to_main_lens_mm;
  const double max_own_radius2 = std::pow(pitch / std::sqrt(3.0) + 0.01, 2);
  const double min_other_radius2 = std::pow(pitch / 2 - 0.01, 2);
  const double white = cam.white_level_dn;
  const double electrons_per_dn = cam.full_well_e > 0 ? cam.full_well_e / 255.0 : 0.0;
  const std::uint64_t seed = SplitMix(options.noise_seed);
  const KernelTable kernels(pitch / 4.0);
  const Pose cam_from_world = world_from_cam.inverse();

  tbb::parallel_for(j_min, j_max + 1, [&](int j) {
    const int tile_size = 2 * reach + 1;
    std::vector<Eigen::Vector3f> tile(tile_size * tile_size);
    std::vector<std::uint8_t> own(tile_size * tile_size), lit(tile_size * tile_size);
    std::vector<float> sigma(tile_size * tile_size), weight(tile_size * tile_size),
        depth_v(tile_size * tile_size);
    ObjectSubset near;
    for (int i = i_min; i <= i_max; ++i) {
      const Eigen::Vector2d centre = model.LatticeCenterPx(i, j);
      const MicroLens lens = model.Lens(i, j);
      const int x0 = static_cast<int>(std::lround(centre.x())) - reach;
      const int y0 = static_cast<int>(std::lround(centre.y())) - reach;
      if (x0 + tile_size <= 0 || y0 + tile_size <= 0 || x0 >= frame.width || y0 >= frame.height)
        continue;
      const ObjectSubset* subset =
          options.cull_objects && !scene.uniform_white &&
                  ObjectsOfMicroImage(model, scene, world_from_cam, lens, &near)
              ? &near
              : nullptr;
      bool any_own = false;
      for (int ty = 0; ty < tile_size; ++ty)
        for (int tx = 0; tx < tile_size; ++tx) {
          const int idx = ty * tile_size + tx;
          const int x = x0 + tx, y = y0 + ty;
          own[idx] = lit[idx] = 0;
          tile[idx].setZero();
          sigma[idx] = 0;
          weight[idx] = 0;
          depth_v[idx] = kNaN;
          if (x < 0 || y < 0 || x >= frame.width || y >= frame.height) continue;
          const Eigen::Vector2d p(x, y);
          // Inside the hexagon's inscribed circle a pixel is this lens's;
          // beyond its circumcircle it is not; between, ask the lattice.
          const double r2 = (p - centre).squaredNorm();
          if (r2 > max_own_radius2) continue;
          if (r2 >= min_other_radius2) {
            int li = 0, lj = 0;
            model.NearestLens(p, &li, &lj);
            if (li != i || lj != j) continue;
          }
          own[idx] = 1;
          any_own = true;
          const std::optional<PixelSample> sample = model.TraceThroughLens(p, lens);
          if (!sample) continue;
          const double vignetting = sample->coverage * (options.vignetting ? sample->falloff : 1.0);
          if (scene.uniform_white) {
            lit[idx] = 1;
            tile[idx].setOnes();
            weight[idx] = static_cast<float>(vignetting);
            continue;
          }
          Eigen::Vector3d p_in_cam;
          const std::optional<Hit> hit = IntersectLocus(
              model, scene, world_from_cam, cam_from_world, sample->ray,
              [&](double b) { return model.RawLineAt(*sample, p, b); }, &p_in_cam, subset);
          if (!hit || p_in_cam.z() <= cam.main_focal_length_mm) continue;
          const double b = model.ImageDistanceOfDepth(p_in_cam.z());
          const double v = (b - b_l0) / cam.mla_to_sensor_mm;
          const double footprint =
              cam.pixel_size_mm * std::max(std::abs(v), 1.0) * p_in_cam.z() / b;
          lit[idx] = 1;
          tile[idx] = scene.Shade(*hit, footprint).cast<float>();
          weight[idx] = static_cast<float>(vignetting);
          depth_v[idx] = static_cast<float>(v);
          if (options.defocus)
            sigma[idx] = static_cast<float>(
                std::min(model.BlurDiameterPx(sample->lens.type, v), pitch) / 4.0);
        }
      if (!any_own) continue;
      if (options.defocus && !scene.uniform_white)
        BlurTile(tile_size, tile_size, lit, sigma, kernels, &tile);
      for (int ty = 0; ty < tile_size; ++ty)
        for (int tx = 0; tx < tile_size; ++tx) {
          const int idx = ty * tile_size + tx;
          if (!own[idx]) continue;
          const int x = x0 + tx, y = y0 + ty;
          const std::size_t pixel = static_cast<std::size_t>(y) * frame.width + x;
          frame.virtual_depth[pixel] = depth_v[idx];
          Eigen::Vector3d dn = tile[idx].cast<double>() * (white * weight[idx]);
          std::uint8_t* out = frame.pixels.data() + pixel * bpp;
          auto sense = [&](double value, int channel) {
            if (options.sensor_noise) {
              const std::uint64_t index = pixel * 4 + channel;
              double sd2 = cam.read_noise_dn * cam.read_noise_dn;
              if (electrons_per_dn > 0) sd2 += std::max(value, 0.0) / electrons_per_dn;
              if (sd2 > 0) value += std::sqrt(sd2) * Gaussian(seed, index);
            }
            return static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
          };
          if (frame.format == PixelFormat::kMono8) {
            // RGGB: R at (even, even), B at (odd, odd), G elsewhere.
            const int channel = (y % 2 == 0) ? (x % 2 == 0 ? 0 : 1) : (x % 2 == 0 ? 1 : 2);
            out[0] = sense(dn[channel], 0);
          } else {
            out[0] = sense(dn.z(), 0);  // BGR byte order
            out[1] = sense(dn.y(), 1);
            out[2] = sense(dn.x(), 2);
          }
        }
    }
  });
  return frame;
}

TfGroundTruth RenderTfGroundTruth(const PlenopticModel& model, const Scene& scene,
                                  const Pose& world_from_cam) {
  const SynthCameraParams& cam = model.params();
  TfGroundTruth gt;
  gt.width = model.tf_width();
  gt.height = model.tf_height();
  gt.bgr.assign(static_cast<std::size_t>(gt.width) * gt.height * 3, 0);
  gt.depth_mm.assign(static_cast<std::size_t>(gt.width) * gt.height, kNaN);
  gt.region.assign(gt.depth_mm.size(), -1);
  const Pose cam_from_world = world_from_cam.inverse();
  tbb::parallel_for(0, gt.height, [&](int w) {
    for (int u = 0; u < gt.width; ++u) {
      const std::size_t pixel = static_cast<std::size_t>(w) * gt.width + u;
      const Eigen::Vector2d tf(u, w);
      Eigen::Vector3d radiance = Eigen::Vector3d::Ones();
      if (!scene.uniform_white) {
        Eigen::Vector3d p_in_cam;
        const std::optional<Hit> hit = IntersectLocus(
            model, scene, world_from_cam, cam_from_world, model.TfPixelRay(tf),
            [&](double b) { return model.TfLineAt(tf, b); }, &p_in_cam);
        if (!hit || p_in_cam.z() <= cam.main_focal_length_mm) continue;
        const double b = model.ImageDistanceOfDepth(p_in_cam.z());
        radiance = scene.Shade(*hit, 2.0 * cam.pixel_size_mm * p_in_cam.z() / b);
        gt.depth_mm[pixel] = static_cast<float>(p_in_cam.z());
        gt.region[pixel] = scene.Region(*hit);
      }
      const Eigen::Vector3d dn = radiance * cam.white_level_dn;
      std::uint8_t* out = gt.bgr.data() + pixel * 3;
      for (int c = 0; c < 3; ++c)
        out[c] = static_cast<std::uint8_t>(std::clamp(std::lround(dn[2 - c]), 0L, 255L));
    }
  });
  return gt;
}

}  // namespace lifmcr::synth
