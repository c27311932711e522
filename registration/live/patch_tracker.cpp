#include "registration/live/patch_tracker.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace lifmcr::registration {
namespace {

double Spacing(int level) { return static_cast<double>(1 << level); }

}  // namespace

Status PatchTrackOptions::Check() const {
  if (patch_size < 5 || patch_size > 31 || patch_size % 2 == 0)
    return Error{"patch tracking: patch_size: expected an odd number 5..31"};
  if (levels < 1 || levels > 4) return Error{"patch tracking: levels: expected 1..4"};
  if (iterations < 1) return Error{"patch tracking: iterations: expected >= 1"};
  if (!(min_zncc > 0 && min_zncc < 1)) return Error{"patch tracking: min_zncc: expected in (0, 1)"};
  if (!(max_shift_px > 0)) return Error{"patch tracking: max_shift_px: expected > 0"};
  if (!(min_eigen > 0)) return Error{"patch tracking: min_eigen: expected > 0"};
  return Status::Ok();
}

bool MakePatchTemplate(const processing::TfSampler& sampler, const ConstImageView& raw,
                       const Eigen::Vector2d& centre_tf, double v, const PatchTrackOptions& options,
                       PatchTemplate* out) {
  return MakePatchTemplate(
      [&](const Eigen::Vector2d& centre, int size, double step, float* samples) {
        return sampler.Patch(raw, centre, v, size, step, 1, samples);
      },
      centre_tf, options, out);
}

bool MakePatchTemplate(const PatchSampling& sample, const Eigen::Vector2d& centre_tf,
                       const PatchTrackOptions& options, PatchTemplate* out) {
  const int n = options.patch_size, m = n + 2;
  const std::size_t per_level = static_cast<std::size_t>(m) * m;
  out->samples.resize(per_level * options.levels);
  out->inverse_hessian.resize(options.levels);
  out->gradient.resize(options.levels);
  out->mean.resize(options.levels);
  for (int slot = 0; slot < options.levels; ++slot) {
    const int level = options.levels - 1 - slot;  // coarsest first
    const double s = Spacing(level);
    float* t = out->samples.data() + per_level * slot;
    if (!sample(centre_tf, m, s, t)) return false;
    Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
    std::vector<Eigen::Vector2f>& g = out->gradient[slot];
    g.resize(static_cast<std::size_t>(n) * n);
    double sum = 0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const int c = (j + 1) * m + (i + 1);
        const Eigen::Vector2f gi((t[c + 1] - t[c - 1]) / static_cast<float>(2 * s),
                                 (t[c + m] - t[c - m]) / static_cast<float>(2 * s));
        g[static_cast<std::size_t>(j) * n + i] = gi;
        h += gi.cast<double>() * gi.cast<double>().transpose();
        sum += t[c];
      }
    out->mean[slot] = static_cast<float>(sum / (n * n));
    // Texture at the finest level decides (coarse levels are smoother).
    if (level == 0) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(h, Eigen::EigenvaluesOnly);
      if (!(eigen.eigenvalues()(0) / (n * n) >= options.min_eigen)) return false;
    }
    if (std::abs(h.determinant()) < 1e-12) return false;
    out->inverse_hessian[slot] = h.inverse();
  }
  return true;
}

PatchTrack TrackPatch(const processing::TfSampler& sampler, const ConstImageView& raw,
                      const PatchTemplate& tmpl, const Eigen::Vector2d& predicted_tf, double v,
                      const PatchTrackOptions& options, const Eigen::Matrix2d& warp) {
  const int n = options.patch_size, m = n + 2;
  const std::size_t per_level = static_cast<std::size_t>(m) * m;
  PatchTrack result;
  Eigen::Vector2d p = predicted_tf;
  std::vector<float> patch(static_cast<std::size_t>(n) * n);
  // The template's finest options.levels levels (it may have more).
  const int made = static_cast<int>(tmpl.inverse_hessian.size());
  const int levels = std::min(options.levels, made);
  if (levels < 1 || tmpl.samples.size() != per_level * made) return result;
  for (int level = levels - 1; level >= 0; --level) {
    const int slot = made - 1 - level;
    const double s = Spacing(level);
    const float* t = tmpl.samples.data() + per_level * slot;
    const std::vector<Eigen::Vector2f>& g = tmpl.gradient[slot];
    bool converged = false;
    for (int it = 0; it < options.iterations; ++it) {
      if (!sampler.PatchWarped(raw, p, warp, v, n, s, 1, patch.data())) return result;
      double mean = 0;
      for (float value : patch) mean += value;
      mean /= n * n;
      Eigen::Vector2d b = Eigen::Vector2d::Zero();
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const std::size_t k = static_cast<std::size_t>(j) * n + i;
          const double e = (patch[k] - mean) - (t[(j + 1) * m + (i + 1)] - tmpl.mean[slot]);
          b += g[k].cast<double>() * e;
        }
      const Eigen::Vector2d delta = tmpl.inverse_hessian[slot] * b;
      p -= warp * delta;
      if ((p - predicted_tf).norm() > options.max_shift_px) return result;
      if (delta.norm() < 0.03 * s) {
        converged = true;
        break;
      }
    }
    if (level == 0 && !converged) return result;
  }
  // Zero-mean normalised cross-correlation at the final position (finest level).
  const float* t = tmpl.samples.data() + per_level * (made - 1);
  if (!sampler.PatchWarped(raw, p, warp, v, n, 1.0, 1, patch.data())) return result;
  double mean = 0;
  for (float value : patch) mean += value;
  mean /= n * n;
  const double tm = tmpl.mean[made - 1];
  double st = 0, si = 0, sti = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double a = patch[static_cast<std::size_t>(j) * n + i] - mean;
      const double b = t[(j + 1) * m + (i + 1)] - tm;
      st += b * b;
      si += a * a;
      sti += a * b;
    }
  result.zncc = st > 0 && si > 0 ? sti / std::sqrt(st * si) : 0.0;
  result.tf_px = p;
  result.ok = result.zncc >= options.min_zncc;
  return result;
}

}  // namespace lifmcr::registration
