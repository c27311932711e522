#pragma once
// Renders one raw frame of a focused plenoptic camera (plenoptic_model.h)
// looking at a Scene, and its ground truth.
//
// Per raw pixel: find its micro image (nearest lattice centre), trace the
// chief ray through the micro-lens centre and the main lens into the scene,
// shade (radiance, texture band-limited to the pixel's footprint
// s v z / b_L). Then per micro image: defocus blur with a Gaussian of
// sigma = rho / 4 (rho: disc diameter of the pixel's lens type at the pixel's
// virtual depth; a uniform disc of diameter rho has sigma = rho / 4), applied
// separably over the pixels of the same micro image only; vignetting (the
// aperture rim and cos^4 falloff); then the sensor: exposure, optional RGGB
// mosaic, shot noise (Gaussian, variance = signal in electrons), read noise,
// 8-bit quantisation. Noise comes from a counter-based hash of (seed, pixel),
// so a frame is the same for a seed however the work is split over threads.
//
// Work is parallel over rows of micro images (TBB); each pixel is written by
// exactly one task.

#include "config/frames.h"
#include "config/image.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/scene.h"

#include <cstdint>
#include <vector>

namespace lifmcr::synth {

struct RenderOptions {
  bool defocus = true;           // per-type defocus blur
  bool vignetting = true;        // cos^4 falloff (the aperture rim is always there)
  bool sensor_noise = true;      // shot and read noise per the camera params
  std::uint64_t noise_seed = 1;  // noise stream of this frame
  // Per micro image, intersect only the objects near its bundle of rays
  // (Scene::ObjectsInCone; not with distortion); false: every object. The
  // pixels are the same either way.
  bool cull_objects = true;
};

// An 8-bit raw frame (BGR8, or Mono8 RGGB mosaic) and its ground truth.
struct RawFrame {
  int width = 0, height = 0;
  PixelFormat format = PixelFormat::kBgr8;
  std::vector<std::uint8_t> pixels;  // rows of width * bytes per pixel, no padding
  std::vector<float> virtual_depth;  // v per raw pixel, NaN where no surface / dark
  ConstImageView View() const;
};

RawFrame RenderRaw(const PlenopticModel& model, const Scene& scene, const Pose& world_from_cam,
                   const RenderOptions& options);

// Ground truth on the totally focused grid (W/2 x H/2): the all-in-focus
// pinhole image (BGR8, exposure as the raw image without vignetting) and the
// metric depth z (mm, camera frame; NaN where no surface).
struct TfGroundTruth {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bgr;
  std::vector<float> depth_mm;
  std::vector<std::int32_t> region;  // Scene::Region of the surface seen, -1 where none
  ConstImageView View() const;
};

TfGroundTruth RenderTfGroundTruth(const PlenopticModel& model, const Scene& scene,
                                  const Pose& world_from_cam);

}  // namespace lifmcr::synth
