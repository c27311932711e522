// `lifmcr grid IMAGE [--mla FILE] [--textured] [--out FILE.xml]`: fits the
// micro-image lattice to a white image (processing/mla_grid.h) or, with
// --textured, to a raw image of a textured scene when no white image exists
// (processing/grid_from_raw.h); prints it with its residual, compares it with
// the MLA file when one is given, and writes the refined MLA XML.

#include "apps/commands.h"
#include "config/decimal_number.h"
#include "config/text_escape.h"
#include "processing/grid_from_raw.h"
#include "processing/mla_grid.h"
#include "replay/mla_xml.h"
#include "replay/raw_image.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

namespace lifmcr::apps {
namespace {

struct GridOptions {
  std::string white;
  std::string mla;
  std::string out;
  bool textured = false;
  std::optional<double> tcp;          // --tcp
  std::string depth_ranges;           // --depth-ranges MIN:MAX,MIN:MAX,MIN:MAX
};

int Usage(const std::string& message) {
  std::cerr << "lifmcr grid: " << EscapeText(message) << " (see lifmcr grid --help)\n";
  return 2;
}

// "1:3,2.8:4,3.8:100": the sharp virtual-depth range of lens type id 0, 1, 2.
Status ParseDepthRanges(const std::string& text, MlaCalibration* mla) {
  const std::string expected =
      "--depth-ranges: expected MIN:MAX,MIN:MAX,MIN:MAX (virtual depths of lens type id 0, 1, 2, "
      "e.g. 1:3,2.8:4,3.8:100), got '" + text + "'";
  std::size_t start = 0;
  for (int id = 0; id < 3; ++id) {
    const std::size_t end = id < 2 ? text.find(',', start) : text.size();
    if (end == std::string::npos) return Error{expected};
    const std::string part = text.substr(start, end - start);
    const std::size_t colon = part.find(':');
    if (colon == std::string::npos) return Error{expected};
    double range[2] = {0, 0};
    const std::string numbers[2] = {part.substr(0, colon), part.substr(colon + 1)};
    for (int k = 0; k < 2; ++k) {
      const char* first = numbers[k].data();
      const char* last = first + numbers[k].size();
      const auto [ptr, ec] = FromCharsRounded(first, last, range[k]);
      if (numbers[k].empty() || ec != std::errc() || ptr != last || !std::isfinite(range[k]))
        return Error{expected};
    }
    mla->lens_types[id].depth_min = range[0];
    mla->lens_types[id].depth_max = range[1];
    start = end + 1;
  }
  return Status::Ok();
}

int RunGrid(const GridOptions& o) {
  Expected<OwnedImage> white = ReadRawImage(o.white);
  if (!white) {
    std::cerr << "lifmcr grid: " << EscapeText(white.error().message) << "\n";
    return 1;
  }
  // A white image gives the lattice only. The MLA file also holds the total
  // covering plane and each lens type's sharp virtual-depth range, which no
  // image of a white surface shows: they come from --mla or are given here,
  // asked for before the fit rather than refused when writing.
  const bool have_file = !o.mla.empty();
  if (!have_file && (!o.tcp || o.depth_ranges.empty())) {
    return Usage(
        "without --mla, a white image gives the lattice but not the total covering plane "
        "nor the lens types' depth ranges the MLA file holds: give --mla FILE (its values are "
        "kept and its lattice refined), or --tcp V and --depth-ranges MIN:MAX,MIN:MAX,MIN:MAX "
        "(virtual depths, e.g. --tcp 2.2 --depth-ranges 1:3,2.8:4,3.8:100)");
  }
  MlaCalibration given;
  if (!o.depth_ranges.empty()) {
    if (Status s = ParseDepthRanges(o.depth_ranges, &given); !s) return Usage(s.error().message);
  }
  const int w = white->width, h = white->height;
  MlaCalibration base;
  processing::MlaGrid initial;
  if (have_file) {
    Expected<MlaCalibration> mla = ReadMlaXml(o.mla);
    if (!mla) {
      std::cerr << "lifmcr grid: " << EscapeText(mla.error().message) << "\n";
      return 1;
    }
    base = *mla;
    initial = processing::MlaGrid::FromCalibration(base, w, h);
  }
  Expected<processing::GridFitResult> fit =
      o.textured ? processing::FitGridToRawImage(white->View(), have_file ? &initial : nullptr)
                 : processing::FitGridToWhiteImage(white->View(), have_file ? &initial : nullptr);
  if (!fit) {
    std::cerr << "lifmcr grid: " << EscapeText(o.white) << ": " << EscapeText(fit.error().message) << "\n";
    return 1;
  }
  const processing::MlaGrid& grid = fit->grid;
  if (!have_file) {
    base.diameter_px = grid.PitchPx();
    // The colouring (i - j) mod 3: type 1 at +lens_base_x, type 2 at -lens_base_x.
    const Eigen::Vector2d offsets[3] = {{0, 0}, {1, 0}, {-1, 0}};
    for (int t = 0; t < 3; ++t) {
      base.lens_types[t].id = t;
      base.lens_types[t].offset_lens = offsets[t];
    }
  }
  if (o.tcp) base.tcp_virtual_depth = *o.tcp;
  if (!o.depth_ranges.empty()) {
    for (int t = 0; t < 3; ++t) {
      base.lens_types[t].depth_min = given.lens_types[t].depth_min;
      base.lens_types[t].depth_max = given.lens_types[t].depth_max;
    }
  }
  const MlaCalibration refined = grid.ToCalibration(base, w, h);
  std::printf("%s %s: %dx%d\n", o.textured ? "raw image (textured scene)" : "white image",
              o.white.c_str(), w, h);
  std::printf("fitted lattice: %s\n", fit->BriefReport().c_str());
  std::printf(
      "as RayCalibData: diameter %.5f px, rotation %.7f rad, offset (%.4f, %.4f) px (y up)\n",
      refined.diameter_px, refined.rotation_rad, refined.offset_px.x(), refined.offset_px.y());
  if (have_file) {
    // Centre differences between the file's lattice and the fit, over the image.
    double sum2 = 0, worst = 0;
    int n = 0;
    int i_min = 0, i_max = 0, j_min = 0, j_max = 0;
    grid.IndexBounds(w, h, &i_min, &i_max, &j_min, &j_max);
    for (int j = j_min; j <= j_max; ++j)
      for (int i = i_min; i <= i_max; ++i) {
        const Eigen::Vector2d c = grid.Center(i, j);
        if (c.x() < 0 || c.y() < 0 || c.x() > w - 1 || c.y() > h - 1) continue;
        const double d = (initial.Center(i, j) - c).norm();
        sum2 += d * d;
        worst = std::max(worst, d);
        ++n;
      }
    std::printf(
        "vs %s: diameter %+.5f px, rotation %+.7f rad, offset (%+.4f, %+.4f) px; centres "
        "differ by %.4f px RMS, %.4f px at most, over %d lenses\n",
        o.mla.c_str(), refined.diameter_px - base.diameter_px,
        refined.rotation_rad - base.rotation_rad, refined.offset_px.x() - base.offset_px.x(),
        refined.offset_px.y() - base.offset_px.y(), std::sqrt(sum2 / std::max(1, n)), worst, n);
    std::printf("lens types: from the MLA file (type 1 at %s)\n",
                grid.type_sign > 0 ? "+lens_base_x" : "-lens_base_x");
  } else {
    std::printf(
        "lens types: unknown (a white image cannot tell them apart); the written file "
        "numbers them (i - j) mod 3 from the lens nearest the image centre, with the depth "
        "ranges of --depth-ranges\n");
  }
  const std::string out =
      o.out.empty() ? std::filesystem::path(o.white).stem().string() + "_MLA.xml" : o.out;
  if (Status s = WriteMlaXml(out, refined); !s) {
    std::cerr << "lifmcr grid: " << EscapeText(s.error().message) << "\n";
    return 1;
  }
  std::printf("wrote %s\n", out.c_str());
  return 0;
}

}  // namespace

CommandRun AddGridCommand(CLI::App& app) {
  auto o = std::make_shared<GridOptions>();
  app.footer(
      "Reads: IMAGE (BMP, PNG or TIFF; a white image, or with --textured a raw frame of a\n"
      "textured scene) and --mla FILE (RayCalibData XML). Prints the fitted lattice with its\n"
      "residual and, with --mla, how far the file's micro-image centres are from it.\n"
      "Writes: the refined MLA XML (--out, default ./<IMAGE stem>_MLA.xml). Its total covering\n"
      "plane and lens-type depth ranges, which an image of a white surface does not show, come\n"
      "from --mla, or without it from --tcp and --depth-ranges (both then required; they also\n"
      "replace the --mla file's values).\n"
      "Exit codes: 0 written; 1 an input could not be read or the lattice not fitted (the\n"
      "message says why); 2 usage error.");
  app.add_option("IMAGE", o->white, "White image, or a raw frame with --textured (BMP, PNG, TIFF)")
      ->required();
  app.add_flag("--textured", o->textured,
               "IMAGE is a raw frame of a textured scene (no white image exists): the lattice "
               "from the micro-image borders; best started from --mla");
  app.add_option("--mla", o->mla,
                 "MLA file (RayCalibData XML) to start from, compare with and refine; it also "
                 "gives the lens types");
  app.add_option("--out", o->out, "MLA XML to write (default ./<IMAGE stem>_MLA.xml)");
  app.add_option("--tcp", o->tcp,
                 "Total covering plane to write (virtual depth, e.g. 2.2); required without --mla")
      ->check(CLI::Range(0.01, 1000.0));
  app.add_option("--depth-ranges", o->depth_ranges,
                 "Sharp virtual-depth range of lens type id 0, 1, 2 to write, "
                 "MIN:MAX,MIN:MAX,MIN:MAX (e.g. 1:3,2.8:4,3.8:100); required without --mla");
  return [o] { return RunGrid(*o); };
}

}  // namespace lifmcr::apps
