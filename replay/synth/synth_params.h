#pragma once
// Parameters of the synthetic LiFMCR rig (`lifmcr synth`): the physical
// camera (main lens, MLA, sensor), the rig and its motion, the Vicon. Every
// field has a default, a one-line meaning and a unit; presets fill them and a
// YAML file overrides any of them (keys = the field names below, grouped as
// in SynthParams: `camera:`, `rig:`, `vicon:`; see LoadSynthConfig).
//
// Symbols (the paper's; docs/processing.md): f_L main-lens focal length,
// b_L0 main lens -> MLA, B MLA -> sensor, D micro-image pitch, s pixel size,
// v = b / B virtual depth.

#include "config/error.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::synth {

// One focused plenoptic camera (Raytrix-like, Galilean mode).
struct SynthCameraParams {
  // Sensor.
  int width_px = 1024;            // raw image width
  int height_px = 768;            // raw image height
  double pixel_size_mm = 0.0055;  // s
  // Main lens (thin lens) and its distance to the MLA.
  double main_focal_length_mm = 25.0;  // f_L
  double f_number = 2.4;               // aperture diameter = f_L / f_number
  double mla_to_main_lens_mm = 24.80;  // b_L0
  double mla_to_sensor_mm = 0.2042;    // B
  // MLA as seen on the sensor: the lattice of micro-image centres c_k, in the
  // conventions of the Raytrix XML (config/mla.h): pitch D, rotation
  // (counter-clockwise, y up), offset of the reference lens from the image
  // centre (x right, y up).
  double micro_image_pitch_px = 16.0;  // D
  double mla_rotation_rad = 0.0;
  Eigen::Vector2d mla_offset_px = Eigen::Vector2d(0.3, -0.2);
  // Small tilt of the MLA plane about its x and y axes (rad, at most 1e-3):
  // sit at slightly different B; the written XML is then a best fit.
  double mla_tilt_x_rad = 0.0;
  double mla_tilt_y_rad = 0.0;
  // Focal length of the micro lenses of each type (XML ids 0, 1, 2). A type
  // is sharp at v_t with B / f_t = 1 - 1 / v_t (see plenoptic_model.h).
  std::array<double, 3> micro_lens_focal_mm{0.4084, 0.2934, 0.2450};
  // Blur (circle of confusion, px) still counted as sharp: sets the depth
  // range written for each type.
  double sharp_blur_px = 1.6;
  double lens_border_px = 1.0;  // written to the XML
  // LiFCal's distortion in the MLA plane (mm): radial k1, k2 and tangential
  // (Brown) p1, p2; 0 = none.
  double distortion_k1 = 0.0;
  double distortion_k2 = 0.0;
  double distortion_p1 = 0.0;
  double distortion_p2 = 0.0;
  // Sensor response.
  bool bayer = false;           // true: RGGB mosaic written as Mono8; false: BGR8
  double white_level_dn = 200;  // grey level of a white surface at the image centre
  double full_well_e = 8000;    // electrons at 255 DN (shot noise); 0 = no shot noise
  double read_noise_dn = 1.0;   // Gaussian read noise sigma (DN); --noise sets it

  // Every field in range; the message names the field and what it must be.
  Status Check() const;
};

// The two cameras of the paper first, then more (cam index i -> Vicon name).
struct SynthRigParams {
  int cameras = 2;
  int frames = 4;                     // camera triggers per sequence
  std::string motion = "smooth";      // smooth|handheld|axis|circle|orbit (trajectory.h)
  double viewing_distance_mm = 1100;  // camera to the plate centre
  double baseline_mm = 120;           // between neighbouring cameras
  double speed_scale = 1.0;           // scales the amplitude of motion
  // One rigid rig instead of a trajectory per camera: the cameras sit
  // baseline_mm apart along the rig's x, toed in to the look-at point, and
  // move together (c0_from_cx constant).
  bool rigid = false;
  // With rigid: from trigger knock_frame on (-1: never) the last camera sits
  // knock_t_mm further along its x and knock_r_deg turned about its y (a
  // camera knocked on its mount; extrinsic change detection).
  int knock_frame = -1;
  double knock_t_mm = 5.0;
  double knock_r_deg = 0.5;
  std::string scene = "table";                // scene content: table|plain (scene.h)
  std::string scene_folder = "00_Synthetic";  // the scene's folder in the dataset
  std::string sequence = "Sequence_00";       // the sequence's folder in it
  std::uint64_t seed = 1;
  // false: no raw frames, depth or all-in-focus images; poses, Vicon and
  // calibration only (fast inputs for evaluation tests). `--no-images`.
  bool images = true;
  // With images: the triggers whose images are rendered (empty: all). Poses,
  // Vicon and calibration are those of the whole sequence either way, so a
  // few frames of a long sequence (or the rest of a stopped render) come out
  // as they would in the whole. `--render-frames 20-27`.
  std::vector<int> render_frames;
  Status Check() const;
};

struct SynthViconParams {
  int rate_hz = 80;
  int trigger_divider = 8;               // camera trigger every 8th Vicon frame
  std::int64_t first_trigger_frame = 1;  // Vicon frame of the first trigger
  int lead_in_frames = 8;                // Vicon frames recorded before the first trigger
  double marker_noise_mm = 0.15;         // per-marker position noise (sigma)
  int occlusion_gaps = 0;                // gaps per camera subject (0 = none)
  int occlusion_gap_frames = 5;          // length of each gap
  std::string handedness = "left_flip_y";
  std::string rotation = "helical_rad";
  Status Check() const;
};

struct SynthParams {
  std::string preset = "small";
  SynthCameraParams camera;
  SynthRigParams rig;
  SynthViconParams vicon;
  Status Check() const;
};

// "small" (1024x768, D = 16 px, for tests), "medium" (3280x2474, D = 24 px),
// "r32" (6560x4948, 3.2 um, f_L 25 mm, D = 34 px). Error for other names.
Expected<SynthParams> MakePreset(std::string_view name);
std::string_view PresetNames();  // "small|medium|r32"

// Applies the YAML file at `path` on top of `base`. Unknown keys, wrong types
// and out-of-range values are errors naming the file, line, column and key.
Expected<SynthParams> LoadSynthConfig(const std::filesystem::path& path, SynthParams base);
// The same from text (`label` names it in messages).
Expected<SynthParams> ParseSynthConfig(const std::string& text, const std::string& label,
                                       SynthParams base);

}  // namespace lifmcr::synth
