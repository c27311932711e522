#include "evaluation/evaluation_plots.h"

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <vector>

namespace lifmcr {
namespace {

const cv::Scalar kBlack(0, 0, 0), kGrey(150, 150, 150), kLightGrey(225, 225, 225);
const cv::Scalar kBlue(200, 90, 20), kRed(40, 40, 210), kGreen(40, 150, 40), kOrange(0, 140, 255),
    kPurple(150, 50, 150);
const std::vector<cv::Scalar> kPalette{kBlue, kGreen, kRed, kOrange, kPurple};

std::string Num(double v) {
  char text[32];
  const double a = std::abs(v);
  std::snprintf(text, sizeof(text), a >= 100 || v == 0 ? "%.0f" : a >= 1 ? "%.1f" : "%.2f", v);
  return text;
}

// A plot area inside an image: data (x, y) -> pixels, with axes, ticks and labels.
class Panel {
 public:
  Panel(cv::Mat* image, cv::Rect area, double x0, double x1, double y0, double y1,
        const std::string& title, const std::string& x_label, const std::string& y_label,
        bool equal_aspect = false)
      : image_(image), area_(area) {
    if (!(x1 > x0)) x1 = x0 + 1;
    if (!(y1 > y0)) y1 = y0 + 1;
    if (equal_aspect) {
      const double sx = (x1 - x0) / area.width, sy = (y1 - y0) / area.height;
      const double s = std::max(sx, sy);
      const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
      x0 = cx - 0.5 * s * area.width;
      x1 = cx + 0.5 * s * area.width;
      y0 = cy - 0.5 * s * area.height;
      y1 = cy + 0.5 * s * area.height;
    }
    x0_ = x0, x1_ = x1, y0_ = y0, y1_ = y1;
    cv::rectangle(*image_, area_, kBlack, 1);
    for (int k = 0; k <= 4; ++k) {
      const double xv = x0 + (x1 - x0) * k / 4, yv = y0 + (y1 - y0) * k / 4;
      const cv::Point px = Map(xv, y0), py = Map(x0, yv);
      cv::line(*image_, {px.x, area_.y}, {px.x, area_.y + area_.height}, kLightGrey, 1);
      cv::line(*image_, {area_.x, py.y}, {area_.x + area_.width, py.y}, kLightGrey, 1);
      Text(Num(xv), {px.x - 14, area_.y + area_.height + 18}, 0.45);
      Text(Num(yv), {area_.x - 58, py.y + 5}, 0.45);
    }
    cv::rectangle(*image_, area_, kBlack, 1);
    Text(title, {area_.x, area_.y - 10}, 0.6);
    Text(x_label, {area_.x + area_.width / 2 - 40, area_.y + area_.height + 40}, 0.5);
    Text(y_label, {area_.x - 60, area_.y - 10 + (title.empty() ? 0 : -18)}, 0.5);
  }

  cv::Point Map(double x, double y) const {
    return {area_.x + static_cast<int>(std::lround((x - x0_) / (x1_ - x0_) * area_.width)),
            area_.y + area_.height -
                static_cast<int>(std::lround((y - y0_) / (y1_ - y0_) * area_.height))};
  }
  void Line(const std::vector<double>& x, const std::vector<double>& y, const cv::Scalar& color,
            int thickness = 2) {
    std::vector<cv::Point> pts;
    for (std::size_t k = 0; k < x.size(); ++k) pts.push_back(Map(x[k], y[k]));
    if (pts.size() > 1) cv::polylines(*image_, pts, false, color, thickness, cv::LINE_AA);
  }
  void Dots(const std::vector<double>& x, const std::vector<double>& y, const cv::Scalar& color,
            int radius = 2) {
    for (std::size_t k = 0; k < x.size(); ++k)
      cv::circle(*image_, Map(x[k], y[k]), radius, color, cv::FILLED, cv::LINE_AA);
  }
  void HLine(double y, const cv::Scalar& color, bool dashed) {
    const cv::Point a = Map(x0_, y), b = Map(x1_, y);
    if (a.y < area_.y || a.y > area_.y + area_.height) return;
    if (!dashed) {
      cv::line(*image_, a, b, color, 1, cv::LINE_AA);
      return;
    }
    for (int x = a.x; x < b.x; x += 12)
      cv::line(*image_, {x, a.y}, {std::min(x + 6, b.x), a.y}, color, 1, cv::LINE_AA);
  }
  void Bar(double x_from, double x_to, double height, const cv::Scalar& color) {
    cv::Point a = Map(x_from, 0), b = Map(x_to, height);
    cv::rectangle(*image_, cv::Rect(cv::Point(std::min(a.x, b.x), std::min(a.y, b.y)),
                                    cv::Point(std::max(a.x, b.x), std::max(a.y, b.y))),
                  color, 1);
  }
  void Legend(int row, const std::string& text, const cv::Scalar& color) {
    const cv::Point at(area_.x + 10, area_.y + 20 + 20 * row);
    cv::rectangle(*image_, cv::Rect(at.x, at.y - 10, 14, 10), color, cv::FILLED);
    Text(text, {at.x + 20, at.y}, 0.45);
  }
  void Text(const std::string& text, cv::Point at, double scale) {
    cv::putText(*image_, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, kBlack, 1, cv::LINE_AA);
  }

 private:
  cv::Mat* image_;
  cv::Rect area_;
  double x0_ = 0, x1_ = 1, y0_ = 0, y1_ = 1;
};

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void Add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  void Pad(double fraction) {
    if (!(hi >= lo)) lo = 0, hi = 1;
    const double d = std::max(hi - lo, 1e-9) * fraction;
    lo -= d;
    hi += d;
  }
};

Status Write(const std::filesystem::path& path, const cv::Mat& image) {
  try {
    if (cv::imwrite(path.string(), image)) return Status::Ok();
  } catch (const cv::Exception& e) {
    return MakeErrorAt(path.string(), "/", std::string("cannot write the PNG: ") + e.what());
  }
  return MakeErrorAt(path.string(), "/", "cannot write the PNG");
}

}  // namespace

Status PlotTrajectoriesTop(const EvaluationRun& run, const std::filesystem::path& path) {
  cv::Mat image(900, 1100, CV_8UC3, cv::Scalar(255, 255, 255));
  const Pose world_from_vicon = run.plate ? run.plate->vicon_from_world.inverse() : Pose::Identity();
  // Offsets of the first corrected evaluation, per serial.
  std::map<std::string, Pose> offset;
  for (const CameraEvaluation& e : run.evaluations) {
    if (!e.has_correction()) continue;
    offset.emplace(e.serial, e.marker_from_cam);
    offset.emplace(e.reference_serial, e.marker_from_cam_reference);
  }
  struct Track {
    std::vector<double> x, y;
    std::string label;
    bool dots;
  };
  std::vector<Track> tracks;
  Range rx, ry;
  for (const CameraTruth& c : run.cameras) {
    Track t{{}, {}, c.serial + " Vicon" + (offset.count(c.serial) ? " (camera centre)" : " (markers)"), false};
    const Pose x = offset.count(c.serial) ? offset.at(c.serial) : Pose::Identity();
    for (const auto& [f, p] : c.vicon_from_marker) {
      const Eigen::Vector3d c_w = (world_from_vicon * p * x).translation();
      t.x.push_back(c_w.x());
      t.y.push_back(c_w.y());
      rx.Add(c_w.x());
      ry.Add(c_w.y());
    }
    tracks.push_back(std::move(t));
  }
  const CameraTruth* reference = run.Camera(run.reference_serial);
  for (const CameraEvaluation& e : run.evaluations) {
    if (!reference) break;
    Track t{{}, {}, e.serial + " " + e.method + " (placed by " + e.reference_serial + "'s Vicon)",
            true};
    const Pose x0 = e.has_correction() ? e.marker_from_cam_reference : Pose::Identity();
    for (const auto& [f, b] : e.estimate) {
      const auto m0 = reference->vicon_from_marker.find(f);
      if (m0 == reference->vicon_from_marker.end()) continue;
      const Eigen::Vector3d c_w = (world_from_vicon * m0->second * x0 * b).translation();
      t.x.push_back(c_w.x());
      t.y.push_back(c_w.y());
    }
    tracks.push_back(std::move(t));
  }
  if (run.plate)
    for (const Eigen::Vector3d& m : DefaultPlateTemplate().vicon_markers_mm) rx.Add(m.x()), ry.Add(m.y());
  rx.Pad(0.08);
  ry.Pad(0.08);
  Panel panel(&image, cv::Rect(90, 60, 980, 760), rx.lo, rx.hi, ry.lo, ry.hi,
              std::string("Trajectories from above (") + (run.plate ? "plate frame" : "Vicon frame") +
                  ", x-y, mm)",
              "x [mm]", "y [mm]", true);
  if (run.plate) {
    const auto m = DefaultPlateTemplate().vicon_markers_mm;
    for (int k = 0; k < 4; ++k)
      panel.Line({m[k].x(), m[(k + 1) % 4].x()}, {m[k].y(), m[(k + 1) % 4].y()}, kGrey, 1);
    panel.Text("plate", panel.Map(m[0].x(), m[0].y()) + cv::Point(4, -6), 0.45);
  }
  for (std::size_t k = 0; k < tracks.size(); ++k) {
    const cv::Scalar color = kPalette[k % kPalette.size()];
    if (tracks[k].dots)
      panel.Dots(tracks[k].x, tracks[k].y, color, 2);
    else
      panel.Line(tracks[k].x, tracks[k].y, color, 2);
    if (!tracks[k].x.empty())
      panel.Dots({tracks[k].x.front()}, {tracks[k].y.front()}, color, 5);
    panel.Legend(static_cast<int>(k), tracks[k].label, color);
  }
  return Write(path, image);
}

Status PlotErrorsOverFrames(const CameraEvaluation& e, const std::filesystem::path& path) {
  cv::Mat image(900, 1200, CV_8UC3, cv::Scalar(255, 255, 255));
  const PoseErrors& u = e.uncorrected.ape;
  const PoseErrors& c = e.corrected.ape;
  for (int panel_index = 0; panel_index < 2; ++panel_index) {
    const bool rotation = panel_index == 1;
    auto values = [&](const PoseErrors& p) {
      return rotation ? p.rotation_deg : p.translation_mm;
    };
    Range rx, ry;
    ry.Add(0);
    for (const PoseErrors* p : {&u, &c})
      for (std::size_t k = 0; k < p->size(); ++k) {
        rx.Add(static_cast<double>(p->frames[k]));
        ry.Add(values(*p)[k]);
      }
    rx.Pad(0.02);
    ry.hi += 0.08 * (ry.hi - ry.lo + 1e-9);
    Panel panel(&image, cv::Rect(90, 60 + 420 * panel_index, 1060, 320), rx.lo, rx.hi, 0, ry.hi,
                e.method + " " + e.serial + ": absolute " +
                    (rotation ? "rotation error [deg]" : "translation error [mm]") + " per frame",
                "frame", "");
    int legend = 0;
    for (const auto& [p, color, name] :
         {std::tuple{&u, kGrey, std::string("no correction")},
          std::tuple{&c, kBlue, std::string("hand-eye corrected (cross-validated)")}}) {
      if (p->size() == 0) continue;
      std::vector<double> x;
      for (std::int64_t f : p->frames) x.push_back(static_cast<double>(f));
      const std::vector<double> y = values(*p);
      panel.Line(x, y, color, 1);
      const ErrorStats s = ErrorStats::Of(y);
      panel.HLine(s.rmse, color, false);
      panel.HLine(s.median, color, true);
      panel.Legend(legend++, name + ": RMSE " + Num(s.rmse) + " (solid), median " + Num(s.median) +
                                 " (dashed)",
                   color);
    }
  }
  return Write(path, image);
}

Status PlotAxisHistograms(const CameraEvaluation& e, const std::filesystem::path& path) {
  cv::Mat image(820, 1400, CV_8UC3, cv::Scalar(255, 255, 255));
  const char* axes[3] = {"x", "y", "z"};
  for (int row = 0; row < 2; ++row) {
    const bool rotation = row == 1;
    for (int k = 0; k < 3; ++k) {
      auto values = [&](const PoseErrors& p) {
        std::vector<double> v;
        for (std::size_t i = 0; i < p.size(); ++i)
          v.push_back(rotation ? p.rotation_axes_deg[i][k] : p.translation_axes_mm[i][k]);
        return v;
      };
      const std::vector<double> u = values(e.uncorrected.ape);
      const std::vector<double> c = values(e.corrected.ape);
      Range r;
      for (double v : u) r.Add(v);
      for (double v : c) r.Add(v);
      r.Pad(0.05);
      constexpr int kBins = 40;
      const double width = (r.hi - r.lo) / kBins;
      auto histogram = [&](const std::vector<double>& v) {
        std::vector<double> h(kBins, 0);
        for (double x : v)
          h[std::clamp(static_cast<int>((x - r.lo) / width), 0, kBins - 1)] += 1;
        return h;
      };
      const std::vector<double> hu = histogram(u), hc = histogram(c);
      double top = 1;
      for (int b = 0; b < kBins; ++b) top = std::max({top, hu[b], hc[b]});
      Panel panel(&image, cv::Rect(80 + 450 * k, 80 + 400 * row, 380, 280), r.lo, r.hi, 0,
                  top * 1.15,
                  std::string(axes[k]) + (rotation ? " rotation [deg]" : " translation [mm]"),
                  "signed error", "frames");
      for (int b = 0; b < kBins; ++b) {
        if (hu[b] > 0) panel.Bar(r.lo + b * width, r.lo + (b + 1) * width, hu[b], kGrey);
        if (hc[b] > 0) panel.Bar(r.lo + b * width, r.lo + (b + 1) * width, hc[b], kBlue);
      }
      panel.Legend(0, "no correction", kGrey);
      if (!c.empty()) panel.Legend(1, "hand-eye", kBlue);
    }
  }
  cv::putText(image, e.method + " " + e.serial + ": absolute errors per camera axis",
              {80, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.6, kBlack, 1, cv::LINE_AA);
  return Write(path, image);
}

}  // namespace lifmcr
