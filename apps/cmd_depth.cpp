// `lifmcr depth SEQ_DIR --camera SERIAL --frame K --out DIR [--intrinsics
// cameras.yaml]` or `lifmcr depth --raw FILE --mla MLA.xml --out DIR`: one
// raw frame (BMP, PNG or TIFF; replay/raw_image.h) to virtual depth (raw and
// TF grids, with the confidence map on the raw grid), the
// totally focused image, metric depth, a coloured point cloud and the
// per-lens virtual depth with its TF preview, by the
// processing chain replay and `record --publish` run too
// (processing/frame_chain.h; files found by apps/pipeline/camera_setup.h).
// The OpenCV (TIFF, PNG, colour map) boundary of the processing library is
// here; the PLY is processing/ply.h.

#include "apps/commands.h"
#include "apps/pipeline/camera_setup.h"
#include "processing/frame_chain.h"
#include "processing/ply.h"
#include "replay/bayer.h"
#include "config/text_escape.h"
#include "replay/layout.h"
#include "replay/raw_image.h"
#include "replay/sequence.h"
#include "replay/synth/gt_images.h"

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
  std::int64_t frame = 0;            // the frame RunDepth processes
  std::vector<std::string> frames;  // --frame values as typed (default: 0), parsed strictly
  bool all_frames = false;
  std::string out;
  std::string intrinsics;
  std::string white;
  bool no_white = false;
  std::string mla;
  std::string raw;
  std::string pixel_format;
  bool full_search = false;  // the dense search unseeded (the reference)
  bool scalar = false;       // the scalar kernels instead of Highway's (the reference)
};

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

// The per-lens product as text: one row per micro image of the frame
// (docs/processing.md, "Files").
Status WriteLensCsv(const fs::path& path, const processing::LensDepthMap& d) {
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (file == nullptr) return Error{path.string() + ": could not write"};
  std::fprintf(file, "col,row,i,j,type,x_px,y_px,virtual_depth,sigma_z,confidence,textured\n");
  for (int row = 0; row < d.grid.rows; ++row)
    for (int col = 0; col < d.grid.cols; ++col) {
      const std::size_t c = d.Cell(col, row);
      if (d.type[c] < 0) continue;
      int i = 0, j = 0;
      d.grid.Lens(col, row, &i, &j);
      const Eigen::Vector2d centre = d.grid.Centre(col, row);
      std::fprintf(file, "%d,%d,%d,%d,%d,%.3f,%.3f,", col, row, i, j, d.type[c], centre.x(),
                   centre.y());
      if (std::isfinite(d.virtual_depth[c]))
        std::fprintf(file, "%.5f,%.6g,%.4f,%d\n", d.virtual_depth[c], d.sigma_z[c], d.confidence[c],
                     d.textured[c]);
      else
        std::fprintf(file, ",,0,%d\n", d.textured[c]);
    }
  const bool ok = std::ferror(file) == 0;
  if (std::fclose(file) != 0 || !ok) return Error{path.string() + ": could not write"};
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
  const fs::path seq = o.sequence;
  const fs::path raw_path =
      single_file ? fs::path(o.raw) : layout::RawFramePath(seq, o.camera, o.frame);
  if (!o.intrinsics.empty() && o.camera.empty())
    return Usage("--intrinsics needs --camera SERIAL (the camera to look up)");

  auto t = std::chrono::steady_clock::now();
  RawImageInfo raw_info;
  Expected<OwnedImage> raw = ReadRawImage(raw_path, &raw_info);
  if (!raw) return Fail(raw.error().message);
  if (Status s = Demosaic(pixel_format, &*raw); !s)
    return Fail(raw_path.string() + ": " + s.error().message);
  // The same lookup and chain as replay and record --publish: the MLA file
  // (--mla, else the dataset's Calibration/), the white image (--white, else
  // the one beside the MLA file; none with --no-white or --raw alone: the
  // vignetting then comes from the frame, processing/vignetting.h).
  CameraFileOverrides files{o.mla, o.white, o.intrinsics, !o.no_white && !single_file};
  auto setup = LoadSequenceCamera(seq, o.camera, files);
  if (!setup)
    return Fail(setup.error().message +
                " (--mla and --white name other files, --no-white uses no white image)");
  if (setup->white) {
    if (Status s = Demosaic(pixel_format, &*setup->white); !s)
      return Fail("white image: " + s.error().message);
  }
  if (setup->intrinsics && (setup->intrinsics->width_px != raw->width ||
                            setup->intrinsics->height_px != raw->height))
    return Fail(o.intrinsics + ": camera " + o.camera + " is " +
                std::to_string(setup->intrinsics->width_px) + "x" +
                std::to_string(setup->intrinsics->height_px) + ", the raw frame " +
                std::to_string(raw->width) + "x" + std::to_string(raw->height));
  const bool has_white = setup->white.has_value();
  processing::ChainOptions chain_options;
  chain_options.point_cloud = true;
  chain_options.cloud_measured_only = true;
  chain_options.seeded_depth = !o.full_search;
  chain_options.depth.simd = !o.scalar;
  chain_options.lens.simd = !o.scalar;
  auto chain = processing::CameraChain::Create(std::move(*setup), chain_options);
  if (!chain)
    return Fail(chain.error().message +
                (o.intrinsics.empty() ? std::string() : " (--intrinsics " + o.intrinsics + ")"));
  const processing::CameraChain& camera = **chain;
  std::printf(
      "read      %.3f s  %s (%dx%d %s, %s%s)\n", Seconds(t), raw_path.string().c_str(), raw->width,
      raw->height, std::string(ToString(raw->format)).c_str(), raw_info.Describe().c_str(),
      pixel_format && IsBayer(*pixel_format)
          ? (std::string(", demosaiced from ") + std::string(ToString(*pixel_format))).c_str()
          : "");

  // The per-lens depth first: it seeds the dense search (ChainOptions::seeded_depth).
  auto lenses = (*chain)->ProcessLenses(raw->View(), 512);
  if (!lenses) return Fail(raw_path.string() + ": " + lenses.error().message);
  const processing::LensProducts& lens = **lenses;
  auto lease = (*chain)->Process(raw->View(), &lens.depth);
  if (!lease) return Fail(raw_path.string() + ": " + lease.error().message);
  const processing::ChainProducts& p = **lease;
  const processing::VirtualDepthMap& depth = p.raw_depth;
  const processing::TfDepthMap& tf_depth = p.tf_depth;
  const processing::TfImage& tf = p.tf;
  std::printf("prepare   %.3f s  %zu micro images; %s%s\n", p.prepare_s, p.prepared.lenses.size(),
              has_white ? "devignetted by the white image"
                        : ("no white image: " + camera.Describe()).c_str(),
              camera.camera_model()
                  ? ""
                  : "; no intrinsics: micro-lens centres = micro-image centres (lambda 1)");
  const double raw_mp = raw->width * static_cast<double>(raw->height) / 1e6;
  std::printf("lenses    %.3f s  %s\n", lens.depth_s + lens.preview_s, lens.BriefReport().c_str());
  std::printf("depth     %.3f s  %.1f raw MP/s, %s; %s\n", p.seed_s + p.depth_s,
              raw_mp / (p.seed_s + p.depth_s),
              o.full_search ? "full search" : "seeded by the per-lens depth",
              depth.stats.BriefReport().c_str());
  // max(1): an empty TF grid prints 0 %, not -nan %.
  const double tf_n = std::max(1.0, static_cast<double>(tf_depth.width) * tf_depth.height);
  std::printf("tf        %.3f s  %dx%d; TF depth: %.1f %% measured, %.1f %% filled\n", p.tf_s,
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
    const std::string prefix = layout::VirtualDepthFileName(o.camera, o.frame);
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
  if (Status s = WriteLensCsv(out / (stem + "_lens_depth.csv"), lens.depth); !s)
    return Fail(s.error().message);
  if (Status s = synth::WriteFloatTiff(out / (stem + "_lens_depth.tiff"), lens.depth.grid.cols,
                                       lens.depth.grid.rows, lens.depth.virtual_depth);
      !s)
    return Fail(s.error().message);
  if (Status s = synth::WritePng(out / (stem + "_lens_tf.png"), lens.preview.View()); !s)
    return Fail(s.error().message);
  double v_lo = 1e9, v_hi = 0;
  for (const MlaLensType& type : camera.mla().lens_types) {
    v_lo = std::min(v_lo, std::max(1.5, type.depth_min));
    v_hi = std::max(v_hi, type.depth_max);
  }
  if (!(v_hi > v_lo)) v_hi = v_lo + 10;
  if (Status s = WriteDepthPng(out / (stem + "_depth.png"), tf_depth, v_lo, v_hi); !s)
    return Fail(s.error().message);
  if (p.metric) {
    if (Status s = synth::WriteFloatTiff(out / (stem + "_depth_mm.tiff"), tf_depth.width,
                                         tf_depth.height, p.depth_mm);
        !s)
      return Fail(s.error().message);
    // The chain has checked that the intrinsics and the MLA file can give
    // points (processing/frame_chain.h); none left means the frame itself
    // had no measured depth: say what was measured, not just "no points".
    if (p.cloud.points_mm.empty())
      return Fail(raw_path.string() + ": no point for " + stem +
                  "_points.ply: no TF pixel has a measured depth in front of the camera (" +
                  depth.stats.BriefReport() + "; a frame without texture?); the other files are "
                  "written");
    if (Status s = processing::WritePly(out / (stem + "_points.ply"), p.cloud, o.uncertainty); !s)
      return Fail(s.error().message);
    std::printf("cloud     %zu points (measured TF pixels)\n", p.cloud.points_mm.size());
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

// Every frame asked for, one after the other, with a progress line before
// each; the first failure stops (exit 1), the frames before it are written.
int RunDepthFrames(const DepthCommandOptions& o) {
  // Parsed here, not by CLI11, which turns 30 digits into INT64_MAX without a word.
  std::vector<std::int64_t> frames;
  for (const std::string& text : o.frames) {
    std::int64_t frame = -1;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), frame);
    if (text.empty() || ec != std::errc() || end != text.data() + text.size() || frame < 0 ||
        frame > layout::kMaxFrameNumber)
      return Fail("--frame: expected a frame number 0 .. " +
                  std::to_string(layout::kMaxFrameNumber) + ", got '" + Excerpt(text) + "'");
    frames.push_back(frame);
  }
  if (frames.empty()) frames = {0};
  if (o.all_frames) {
    if (!o.raw.empty() || o.sequence.empty()) return Usage("--all-frames needs SEQ_DIR");
    if (!o.frames.empty()) return Usage("--all-frames and --frame exclude each other");
    Expected<SequenceLayout> layout = DiscoverSequence(o.sequence);
    if (!layout) return Fail(layout.error().message);
    frames.clear();
    for (const CameraFolder& camera : layout->cameras)
      if (camera.serial == o.camera) frames = camera.frames;
    if (frames.empty()) return Fail(o.sequence + ": no frames of camera " + o.camera);
  }
  if (!o.raw.empty() && frames.size() > 1)
    return Usage("--raw takes one file; --frame applies to SEQ_DIR");
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    DepthCommandOptions one = o;
    one.frame = frames[k];
    if (frames.size() > 1)
      std::printf("frame %zu/%zu: %lld (%.0f s so far)\n", k + 1, frames.size(),
                  static_cast<long long>(frames[k]), Seconds(start));
    std::fflush(stdout);
    if (const int code = RunDepth(one); code != 0) return code;
  }
  if (frames.size() > 1) std::printf("%zu frames in %.1f s\n", frames.size(), Seconds(start));
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
      "Writes: into --out, <stem>_virtual_depth.tiff, _confidence.tiff (raw grid, float32),\n"
      "_virtual_depth_tf.tiff, _tf.png, _depth.png (TF grid), the per-lens depth\n"
      "_lens_depth.csv (col,row,i,j,type,x_px,y_px,virtual_depth,sigma_z,confidence,textured;\n"
      "one row per micro image), _lens_depth.tiff (float32, the lens grid) and _lens_tf.png\n"
      "(TF preview at each lens's depth), and with --intrinsics _depth_mm.tiff and\n"
      "_points.ply; <stem> is <serial>_<frame> or the --raw file's stem.\n"
      "Progress: each stage's time per frame, and with several frames (--frame A B ..,\n"
      "--all-frames) a line before each.\n"
      "Exit codes: 0 written; 1 an input could not be read or processed (the message names\n"
      "it; the frames before it are written); 2 usage error.");
  app.add_option("SEQ_DIR", o->sequence, "Sequence folder (SCENE/SEQ of a LiFMCR dataset)");
  app.add_option("--raw", o->raw,
                 "One raw image (BMP, PNG or TIFF, 8 or 16 bits) instead of SEQ_DIR; needs --mla");
  app.add_option("--camera", o->camera,
                 "Camera serial (with SEQ_DIR; with --raw, the serial looked up in --intrinsics)");
  app.add_option("--frame", o->frames,
                 "Frame number(s) in SEQ_DIR (default 0); several are processed in turn");
  app.add_flag("--all-frames", o->all_frames, "Every frame of the camera in SEQ_DIR");
  app.add_option("--out", o->out, "Output folder (created if needed)")->required();
  app.add_option("--intrinsics", o->intrinsics,
                 "cameras.yaml with the camera's model (metric depth and point cloud)");
  app.add_option("--white", o->white,
                 "White image (default: the one beside the MLA file in Calibration/ when it "
                 "exists)");
  app.add_flag("--no-white", o->no_white,
               "Use no white image: vignetting from the frame, or none if already corrected");
  app.add_option("--pixel-format", o->pixel_format,
                 "BayerRG8|BayerGR8|BayerGB8|BayerBG8: demosaic the raw and white image (colour "
                 "TF image, depth on luminance); Mono8/BGR8: as read (default)");
  app.add_option("--mla", o->mla, "MLA XML (default: the dataset's Calibration folder)");
  app.add_flag("--full-search", o->full_search,
               "Dense virtual depth by the full search (the reference) instead of the search "
               "seeded by the per-lens depth");
  app.add_flag("--scalar", o->scalar,
               "The scalar search kernels (the reference) instead of the SIMD ones; the same maps");
  app.add_flag("--uncertainty", o->uncertainty,
               "Add a sigma_z_mm property (standard deviation of the depth) to every PLY point");
  return [o] { return RunDepthFrames(*o); };
}

}  // namespace lifmcr::apps
