// `lifmcr depth SEQ_DIR --camera SERIAL --frame K --out DIR [--intrinsics
// cameras.yaml]` or `lifmcr depth --raw FILE --mla MLA.xml --out DIR`: one
// raw frame (BMP, PNG or TIFF; replay/raw_image.h) to virtual depth (raw and
// TF grids, with the confidence map on the raw grid), the
// totally focused image, metric depth and a coloured point cloud
// (processing/). The OpenCV (TIFF, PNG, colour map) boundary of the
// processing library is here; the PLY is processing/ply.h.

#include "apps/commands.h"
#include "processing/camera_model.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/ply.h"
#include "processing/point_cloud.h"
#include "processing/total_focus.h"
#include "processing/vignetting.h"
#include "processing/virtual_depth.h"
#include "replay/bayer.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/raw_image.h"
#include "replay/synth/cameras_yaml.h"
#include "replay/synth/gt_images.h"
#include "config/text_escape.h"

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;

struct DepthCommandOptions {
  bool uncertainty = false;
  std::string sequence;
  std::string camera;
  std::string frame = "0";
  std::string out;
  std::string intrinsics;
  std::string white;
  bool no_white = false;
  std::string mla;
  std::string raw;
  std::string pixel_format;
};

// The camera `serial` of a cameras.yaml (GroundTruth of `lifmcr synth`, or
// what `lifmcr calibrate` writes), through the strict YAML reader.
Expected<processing::CameraIntrinsics> ReadIntrinsics(const std::string& path,
                                                      const std::string& serial) {
  Expected<synth::CameraModelYaml> model = synth::ReadCameraModelYaml(path, serial);
  if (!model) return model.error();
  processing::CameraIntrinsics k;
  k.width_px = model->width_px;
  k.height_px = model->height_px;
  k.pixel_size_mm = model->pixel_size_mm;
  k.main_focal_length_mm = model->main_focal_length_mm;
  k.mla_to_main_lens_mm = model->mla_to_main_lens_mm;
  k.mla_to_sensor_mm = model->mla_to_sensor_mm;
  k.k1 = model->k1;
  k.k2 = model->k2;
  k.p1 = model->p1;
  k.p2 = model->p2;
  if (Status s = k.Check(); !s) return Error{EscapeText(path) + ": " + s.error().message};
  return k;
}

// A frame number: decimal digits only, within int64 (CLI11 would turn 30
// digits into INT64_MAX without a word).
Expected<std::int64_t> ParseFrameNumber(const std::string& text) {
  std::int64_t frame = -1;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), frame);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || frame < 0 ||
      frame > layout::kMaxFrameNumber) {
    return Error{"--frame: expected a frame number 0 .. " + std::to_string(layout::kMaxFrameNumber) +
                 ", got '" + Excerpt(text) + "'"};
  }
  return frame;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Colour map of 1/v (near = warm), black where there is no depth.
Status WriteDepthPng(const fs::path& path, const processing::TfDepthMap& depth, double v_min,
                     double v_max) {
  cv::Mat grey(depth.height, depth.width, CV_8UC1);
  cv::Mat valid(depth.height, depth.width, CV_8UC1);
  for (int y = 0; y < depth.height; ++y)
    for (int x = 0; x < depth.width; ++x) {
      const float v = depth.virtual_depth[static_cast<std::size_t>(y) * depth.width + x];
      const bool ok = !std::isnan(v);
      const double t = ok ? (1.0 / v - 1.0 / v_max) / (1.0 / v_min - 1.0 / v_max) : 0.0;
      grey.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(std::clamp(t, 0.0, 1.0) * 255);
      valid.at<std::uint8_t>(y, x) = ok ? 255 : 0;
    }
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_TURBO);
  colour.setTo(cv::Scalar(0, 0, 0), valid == 0);
  try {
    if (!cv::imwrite(path.string(), colour)) return Error{path.string() + ": could not write"};
  } catch (const cv::Exception& e) {
    return Error{path.string() + ": " + e.what()};
  }
  return Status::Ok();
}

int Fail(const std::string& message) {
  std::cerr << "lifmcr depth: " << EscapeText(message) << "\n";
  return 1;
}

int Usage(const std::string& message) {
  std::cerr << "lifmcr depth: " << EscapeText(message) << " (see lifmcr depth --help)\n";
  return 2;
}

// A Bayer mosaic demosaiced in place of `image` (the BGR8 image is the copy
// replay/bayer.h describes); other formats unchanged.
Status Demosaic(std::optional<CameraPixelFormat> format, OwnedImage* image) {
  if (!format || !IsBayer(*format)) return Status::Ok();
  if (image->format != PixelFormat::kMono8)
    return Error{"--pixel-format " + std::string(ToString(*format)) +
                 ": expected a grey (Mono8) mosaic, the file is colour"};
  OwnedImage colour = OwnedImage::Allocate(image->width, image->height, PixelFormat::kBgr8);
  if (Status s = DemosaicBayer(image->View(), *format, colour.View()); !s) return s;
  *image = std::move(colour);
  return Status::Ok();
}

int RunDepth(const DepthCommandOptions& o) {
  const auto t_all = std::chrono::steady_clock::now();
  const bool single_file = !o.raw.empty();
  if (single_file == !o.sequence.empty())
    return Usage("give either SEQ_DIR (with --camera and --frame) or --raw FILE");
  if (!single_file && o.camera.empty()) return Usage("SEQ_DIR needs --camera SERIAL");
  if (single_file && o.mla.empty()) return Usage("--raw needs --mla (the camera's MLA XML)");
  if (!o.white.empty() && o.no_white) return Usage("--white and --no-white exclude each other");
  std::optional<CameraPixelFormat> pixel_format;
  if (!o.pixel_format.empty()) {
    pixel_format = ParseCameraPixelFormat(o.pixel_format);
    if (!pixel_format)
      return Usage("--pixel-format " + o.pixel_format +
                   ": expected Mono8, BGR8, BayerRG8, BayerGR8, BayerGB8 or BayerBG8");
  }
  const Expected<std::int64_t> frame_number = ParseFrameNumber(o.frame);
  if (!frame_number) return Fail(frame_number.error().message);
  const std::int64_t frame_index = *frame_number;
  const fs::path seq = o.sequence;
  const fs::path calib = seq.parent_path().parent_path() / std::string(layout::kCalibrationFolder);
  const fs::path raw_path =
      single_file ? fs::path(o.raw) : layout::RawFramePath(seq, o.camera, frame_index);
  // The white image: --white, else the dataset's when it exists; none with
  // --no-white, with --raw alone, or when the dataset has none (the
  // vignetting then comes from the frame, processing/vignetting.h).
  fs::path white_path = o.white;
  if (white_path.empty() && !o.no_white && !single_file) {
    const fs::path dataset_white = layout::WhiteImagePath(calib, o.camera, 0);
    std::error_code ec;
    if (fs::exists(dataset_white, ec)) white_path = dataset_white;
  }
  const fs::path mla_path = o.mla.empty() ? layout::MlaXmlPath(calib, o.camera) : fs::path(o.mla);

  auto t = std::chrono::steady_clock::now();
  RawImageInfo raw_info;
  Expected<OwnedImage> raw = ReadRawImage(raw_path, &raw_info);
  if (!raw) return Fail(raw.error().message);
  if (Status s = Demosaic(pixel_format, &*raw); !s)
    return Fail(raw_path.string() + ": " + s.error().message);
  std::optional<OwnedImage> white;
  if (!white_path.empty()) {
    Expected<OwnedImage> read = ReadRawImage(white_path);
    if (!read)
      return Fail(read.error().message +
                  " (white image; --white names another, --no-white uses none)");
    if (Status s = Demosaic(pixel_format, &*read); !s)
      return Fail(white_path.string() + ": " + s.error().message);
    white = std::move(*read);
  }
  Expected<MlaCalibration> mla = ReadMlaXml(mla_path);
  if (!mla) return Fail(mla.error().message + " (MLA file; --mla names another)");
  std::optional<processing::CameraModel> camera;
  if (!o.intrinsics.empty()) {
    if (o.camera.empty())
      return Usage("--intrinsics needs --camera SERIAL (the camera to look up)");
    Expected<processing::CameraIntrinsics> k = ReadIntrinsics(o.intrinsics, o.camera);
    if (!k) return Fail(k.error().message);
    if (k->width_px != raw->width || k->height_px != raw->height)
      return Fail(o.intrinsics + ": camera " + o.camera + " is " + std::to_string(k->width_px) +
                  "x" + std::to_string(k->height_px) + ", the raw frame " +
                  std::to_string(raw->width) + "x" + std::to_string(raw->height));
    camera.emplace(*k);
  }
  std::printf(
      "read      %.3f s  %s (%dx%d %s, %s%s)\n", Seconds(t), raw_path.string().c_str(), raw->width,
      raw->height, std::string(ToString(raw->format)).c_str(), raw_info.Describe().c_str(),
      pixel_format && IsBayer(*pixel_format)
          ? (std::string(", demosaiced from ") + std::string(ToString(*pixel_format))).c_str()
          : "");

  t = std::chrono::steady_clock::now();
  const processing::MlaGrid grid =
      processing::MlaGrid::FromCalibration(*mla, raw->width, raw->height);
  processing::FrameOptions frame_options;
  frame_options.lambda = camera ? camera->lambda() : 1.0;
  std::string devignetting = "devignetted by " + white_path.string();
  processing::VignettingEstimate estimate;
  if (!white) {
    processing::VignettingOptions vignetting_options;
    vignetting_options.row_step = raw->height > 2000 ? 4 : 1;
    Expected<processing::VignettingEstimate> e =
        processing::EstimateVignetting(raw->View(), grid, *mla, vignetting_options);
    if (!e) return Fail(raw_path.string() + ": " + e.error().message);
    estimate = std::move(*e);
    devignetting = estimate.BriefReport();
  }
  processing::PlenopticFrame frame;
  if (Status s = processing::PrepareFrame(raw->View(),
                                          white ? ConstImageView(white->View()) : estimate.White(),
                                          grid, *mla, frame_options, &frame);
      !s)
    return Fail(s.error().message);
  if (frame.lenses.empty()) {
    return Fail(raw_path.string() + ": no whole micro image of diameter " +
                std::to_string(mla->diameter_px) + " px fits the " + std::to_string(raw->width) +
                "x" + std::to_string(raw->height) + " frame; expected a raw frame of the camera " +
                "the MLA file belongs to");
  }
  std::printf("prepare   %.3f s  %zu micro images; %s%s\n", Seconds(t), frame.lenses.size(),
              devignetting.c_str(),
              camera ? "" : "; no intrinsics: micro-lens centres = micro-image centres (lambda 1)");

  t = std::chrono::steady_clock::now();
  processing::VirtualDepthMap depth;
  if (Status s = processing::EstimateVirtualDepth(frame, *mla, processing::DepthOptions{}, &depth);
      !s)
    return Fail(s.error().message);
  const double raw_mp = raw->width * static_cast<double>(raw->height) / 1e6;
  std::printf("depth     %.3f s  %.1f raw MP/s; %s\n", Seconds(t), raw_mp / Seconds(t),
              depth.stats.BriefReport().c_str());

  t = std::chrono::steady_clock::now();
  const processing::TfOptions tf_options;
  processing::TfDepthMap tf_depth;
  if (Status s = processing::VirtualDepthToTf(frame, depth, tf_options, &tf_depth); !s)
    return Fail(s.error().message);
  processing::TfImage tf;
  if (Status s = processing::RenderTotalFocus(frame, *mla, tf_depth, tf_options, &tf); !s)
    return Fail(s.error().message);
  // max(1): an empty TF grid prints 0 %, not -nan %.
  const double tf_n = std::max(1.0, static_cast<double>(tf_depth.width) * tf_depth.height);
  std::printf("tf        %.3f s  %dx%d; TF depth: %.1f %% measured, %.1f %% filled\n", Seconds(t),
              tf.width, tf.height, 100.0 * tf_depth.measured / tf_n,
              100.0 * tf_depth.filled / tf_n);

  t = std::chrono::steady_clock::now();
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": " + ec.message());
  const fs::path out = o.out;
  // <serial>_<frame>_* for a dataset frame, <file stem>_* for --raw.
  std::string stem = raw_path.stem().string();
  if (!single_file) {
    const std::string prefix = layout::VirtualDepthFileName(o.camera, frame_index);
    stem = prefix.substr(0, prefix.size() - std::string("_virtual_depth.tiff").size());
  }
  if (Status s = synth::WriteFloatTiff(out / (stem + "_virtual_depth.tiff"), depth.width,
                                       depth.height, depth.virtual_depth);
      !s)
    return Fail(s.error().message);
  if (Status s = synth::WriteFloatTiff(out / (stem + "_virtual_depth_tf.tiff"), tf_depth.width,
                                       tf_depth.height, tf_depth.virtual_depth);
      !s)
    return Fail(s.error().message);
  if (Status s = synth::WriteFloatTiff(out / (stem + "_confidence.tiff"), depth.width, depth.height,
                                       depth.confidence);
      !s)
    return Fail(s.error().message);
  if (Status s = synth::WritePng(out / (stem + "_tf.png"), tf.View()); !s)
    return Fail(s.error().message);
  double v_lo = 1e9, v_hi = 0;
  for (const MlaLensType& type : mla->lens_types) {
    v_lo = std::min(v_lo, std::max(1.5, type.depth_min));
    v_hi = std::max(v_hi, type.depth_max);
  }
  if (!(v_hi > v_lo)) v_hi = v_lo + 10;
  if (Status s = WriteDepthPng(out / (stem + "_depth.png"), tf_depth, v_lo, v_hi); !s)
    return Fail(s.error().message);
  if (camera) {
    std::vector<float> depth_mm;
    processing::MetricDepthTf(*camera, tf_depth, &depth_mm);
    if (Status s = synth::WriteFloatTiff(out / (stem + "_depth_mm.tiff"), tf_depth.width,
                                         tf_depth.height, depth_mm);
        !s)
      return Fail(s.error().message);
    processing::PointCloud cloud;
    processing::BuildPointCloud(*camera, tf_depth, tf, true, &cloud);
    if (Status s = processing::WritePly(out / (stem + "_points.ply"), cloud, o.uncertainty); !s)
      return Fail(s.error().message);
    std::printf("cloud     %zu points (measured TF pixels)\n", cloud.points_mm.size());
  } else {
    std::printf(
        "no --intrinsics: no %s_depth_mm.tiff and no %s_points.ply (metric needs f_L, "
        "b_L0, B)\n",
        stem.c_str(), stem.c_str());
  }
  std::printf("write     %.3f s  %s/%s_*\n", Seconds(t), o.out.c_str(), stem.c_str());
  std::printf("total     %.3f s\n", Seconds(t_all));
  return 0;
}

}  // namespace

CommandRun AddDepthCommand(CLI::App& app) {
  auto o = std::make_shared<DepthCommandOptions>();
  app.footer(
      "Reads: SEQ_DIR/TypeE_<serial>/TypeE_<serial>_<frame>_Raw.bmp, or --raw FILE (BMP, PNG,\n"
      "TIFF; 16-bit scaled to 8); the MLA XML (--mla, else Calibration/02_MLA_Calibration/\n"
      "beside the scene); the white image (--white, else Calibration/01_White_Images/ when it\n"
      "exists; without one the vignetting comes from the frame, or the frame is taken as\n"
      "already devignetted, and the output says which); --intrinsics cameras.yaml.\n"
      "Writes into --out: <stem>_virtual_depth.tiff, _confidence.tiff (raw grid, float32),\n"
      "_virtual_depth_tf.tiff, _tf.png, _depth.png (TF grid), and with --intrinsics\n"
      "_depth_mm.tiff and _points.ply; <stem> is <serial>_<frame> or the --raw file's stem.\n"
      "Exit codes: 0 written; 1 an input could not be read or processed (the message names\n"
      "it); 2 usage error.");
  app.add_option("SEQ_DIR", o->sequence, "Sequence folder (SCENE/SEQ of a LiFMCR dataset)");
  app.add_option("--raw", o->raw,
                 "One raw image (BMP, PNG or TIFF, 8 or 16 bits) instead of SEQ_DIR; needs --mla");
  app.add_option("--camera", o->camera,
                 "Camera serial (with SEQ_DIR; with --raw, the serial looked up in --intrinsics)");
  app.add_option("--frame", o->frame, "Frame number in SEQ_DIR (default 0)");
  app.add_option("--out", o->out, "Output folder (created if needed)")->required();
  app.add_option("--intrinsics", o->intrinsics,
                 "cameras.yaml with the camera's model (metric depth and point cloud)");
  app.add_option("--white", o->white,
                 "White image (default: the dataset's Calibration folder when it holds one)");
  app.add_flag("--no-white", o->no_white,
               "Use no white image: vignetting from the frame, or none if already corrected");
  app.add_option("--pixel-format", o->pixel_format,
                 "BayerRG8|BayerGR8|BayerGB8|BayerBG8: demosaic the raw and white image (colour "
                 "TF image, depth on luminance); Mono8/BGR8: as read (default)");
  app.add_option("--mla", o->mla, "MLA XML (default: the dataset's Calibration folder)");
  app.add_flag("--uncertainty", o->uncertainty,
               "Add a sigma_z_mm property (standard deviation of the depth) to every PLY point");
  return [o] { return RunDepth(*o); };
}

}  // namespace lifmcr::apps
