#include "registration/features/calibration_frames.h"

#include "processing/total_focus.h"
#include "processing/virtual_depth.h"
#include "registration/features/plate_plane.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/sequence.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

namespace lifmcr::registration {

namespace fs = std::filesystem;

namespace {

constexpr char kFrameMagic[8] = {'L', 'F', 'M', 'C', 'R', 'F', 'R', 'M'};
// Version 2: plate corners from the markers' edges (marker_edges.h); a
// version-1 file holds cornerSubPix corners and is processed again.
// Version 3: the principal point and keypoint limit beside lambda.
// Version 4: each keypoint's virtual depth range over its support, and the
// support's radius beside the keypoint limit.
// Version 5: plate corners placed on the plate's TF image rendered at the
// plate plane's virtual depth (plate_plane.h).
// Version 6: keypoints without OpenCV's +1/4 px (features.h).
constexpr std::uint32_t kFrameVersion = 6;

// What a frame was processed with, as stored: lambda, the principal point of
// l_k (NaN NaN: the image centre), the keypoint limit.
struct ProcessedWith {
  double lambda = 0;
  double principal_point_px[2] = {0, 0};
  std::int64_t max_features = 0;
  std::int64_t support_radius_tf_px = 0;
};

ProcessedWith Key(const FrameLoaderOptions& o) {
  ProcessedWith k;
  k.lambda = o.lambda;
  k.principal_point_px[0] = o.principal_point_px ? o.principal_point_px->x() : std::nan("");
  k.principal_point_px[1] = o.principal_point_px ? o.principal_point_px->y() : std::nan("");
  k.max_features = o.features.max_features;
  k.support_radius_tf_px = o.keypoint_support.radius_tf_px;
  return k;
}

// Equal doubles, NaN equal to NaN (an unset principal point).
bool Same(double a, double b) { return (std::isnan(a) && std::isnan(b)) || a == b; }

template <typename T>
void PutVector(std::ostream& out, const std::vector<T>& v) {
  const std::uint64_t n = v.size();
  out.write(reinterpret_cast<const char*>(&n), sizeof(n));
  out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(n * sizeof(T)));
}
template <typename T>
bool GetVector(std::istream& in, std::vector<T>* v) {
  std::uint64_t n = 0;
  if (!in.read(reinterpret_cast<char*>(&n), sizeof(n)) || n > (1ull << 32)) return false;
  v->resize(n);
  return static_cast<bool>(
      in.read(reinterpret_cast<char*>(v->data()), static_cast<std::streamsize>(n * sizeof(T))));
}

}  // namespace

Status SaveCalibrationFrame(const fs::path& path, const CalibrationFrame& f,
                            const FrameLoaderOptions& processed_with) {
  const ProcessedWith key = Key(processed_with);
  std::ofstream out(path, std::ios::binary);
  out.write(kFrameMagic, sizeof(kFrameMagic));
  out.write(reinterpret_cast<const char*>(&kFrameVersion), sizeof(kFrameVersion));
  out.write(reinterpret_cast<const char*>(&key.lambda), sizeof(double));
  out.write(reinterpret_cast<const char*>(key.principal_point_px), 2 * sizeof(double));
  out.write(reinterpret_cast<const char*>(&key.max_features), sizeof(std::int64_t));
  out.write(reinterpret_cast<const char*>(&key.support_radius_tf_px), sizeof(std::int64_t));
  out.write(reinterpret_cast<const char*>(&f.frame), sizeof(f.frame));
  PutVector(out, std::vector<char>(f.name.begin(), f.name.end()));
  const std::int32_t size[2] = {f.tf_width, f.tf_height};
  out.write(reinterpret_cast<const char*>(size), sizeof(size));
  PutVector(out, f.features.keypoints);
  PutVector(out, f.features.descriptors);
  PutVector(out, f.virtual_depth);
  PutVector(out, f.virtual_depth_range);
  PutVector(out, f.rgb);
  PutVector(out, f.corners);
  PutVector(out, f.corner_virtual_depth);
  out.write(reinterpret_cast<const char*>(&f.tf_depth_coverage), sizeof(double));
  if (!out) return Error{path.string() + ": could not write"};
  return Status::Ok();
}

Expected<CalibrationFrame> LoadCalibrationFrame(const fs::path& path,
                                                const FrameLoaderOptions& processed_with) {
  const ProcessedWith key = Key(processed_with);
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path.string() + ": cannot open"};
  char magic[8];
  std::uint32_t version = 0;
  ProcessedWith file;
  CalibrationFrame f;
  std::vector<char> name;
  std::int32_t size[2];
  if (!in.read(magic, 8) || std::memcmp(magic, kFrameMagic, 8) != 0 ||
      !in.read(reinterpret_cast<char*>(&version), sizeof(version)) || version != kFrameVersion ||
      !in.read(reinterpret_cast<char*>(&file.lambda), sizeof(double)) ||
      !in.read(reinterpret_cast<char*>(file.principal_point_px), 2 * sizeof(double)) ||
      !in.read(reinterpret_cast<char*>(&file.max_features), sizeof(std::int64_t)) ||
      !in.read(reinterpret_cast<char*>(&file.support_radius_tf_px), sizeof(std::int64_t)))
    return Error{path.string() + ": not a processed calibration frame (LFMCRFRM, version " +
                 std::to_string(kFrameVersion) + ")"};
  if (std::abs(file.lambda - key.lambda) > 1e-12)
    return Error{path.string() + ": processed with another lambda"};
  if (!Same(file.principal_point_px[0], key.principal_point_px[0]) ||
      !Same(file.principal_point_px[1], key.principal_point_px[1]))
    return Error{path.string() + ": processed with another principal point"};
  if (file.max_features != key.max_features)
    return Error{path.string() + ": processed with another keypoint limit"};
  if (file.support_radius_tf_px != key.support_radius_tf_px)
    return Error{path.string() + ": processed with another keypoint depth support"};
  if (!in.read(reinterpret_cast<char*>(&f.frame), sizeof(f.frame)) || !GetVector(in, &name) ||
      !in.read(reinterpret_cast<char*>(size), sizeof(size)) ||
      !GetVector(in, &f.features.keypoints) || !GetVector(in, &f.features.descriptors) ||
      !GetVector(in, &f.virtual_depth) || !GetVector(in, &f.virtual_depth_range) ||
      !GetVector(in, &f.rgb) || !GetVector(in, &f.corners) ||
      !GetVector(in, &f.corner_virtual_depth) ||
      !in.read(reinterpret_cast<char*>(&f.tf_depth_coverage), sizeof(double)))
    return Error{path.string() + ": ends early"};
  f.name.assign(name.begin(), name.end());
  f.tf_width = size[0];
  f.tf_height = size[1];
  if (f.features.descriptors.size() != f.features.keypoints.size() * kDescriptorSize ||
      f.virtual_depth.size() != f.features.keypoints.size() ||
      f.virtual_depth_range.size() != f.features.keypoints.size() ||
      f.rgb.size() != f.features.keypoints.size() ||
      f.corner_virtual_depth.size() != f.corners.size())
    return Error{path.string() + ": inconsistent sizes"};
  return f;
}

struct CalibrationFrameLoader::State {
  fs::path sequence_dir;
  std::string serial;
  CameraFolder folder;
  MlaCalibration mla;
  OwnedImage white;
  PlateLayout plate;
  FrameLoaderOptions options;
  processing::PlenopticFrame frame;  // geometry prepared once; buffers reused
  processing::VirtualDepthMap depth;
  processing::TfDepthMap tf_depth;
  processing::TfImage tf;
  // The TF depth map with the plate plane's depth over the markers, and the
  // TF image rendered from it (where the corners are placed). A copy of the
  // measured map (4 bytes per TF pixel, kept for the keypoints' and corners'
  // depths): RenderTotalFocus takes a whole map; the copy and the second
  // render cost about 0.3 s of CPU per `medium` frame against 3.2 s for its
  // processing.
  processing::TfDepthMap plate_depth;
  processing::TfImage plate_tf;
};

CalibrationFrameLoader::~CalibrationFrameLoader() = default;

ConstImageView CalibrationFrameLoader::last_tf_image() const { return state_->tf.View(); }

const std::vector<float>& CalibrationFrameLoader::last_tf_virtual_depth() const {
  return state_->tf_depth.virtual_depth;
}

Expected<std::vector<PlateCorner>> CalibrationFrameLoader::PlaceCornersAtPlane(
    std::int64_t frame_number, const std::vector<PlateMarker>& markers, const PlatePlane& plane,
    const MarkerEdgeOptions& edges) {
  State& st = *state_;
  if (markers.empty()) return std::vector<PlateCorner>{};
  const std::optional<fs::path> path = st.folder.FramePath(frame_number);
  if (!path)
    return Error{st.folder.dir.string() + ": no raw frame " + std::to_string(frame_number)};
  Expected<OwnedImage> raw = ReadBmp(*path);
  if (!raw) return raw.error();
  if (raw->width != width_ || raw->height != height_)
    return Error{path->string() + ": " + std::to_string(raw->width) + "x" +
                 std::to_string(raw->height) + ", the first frame " + std::to_string(width_) +
                 "x" + std::to_string(height_)};
  if (Status s = processing::LoadRaw(raw->View(), &st.frame); !s) return s.error();
  // The TF grid of processing/total_focus.h: half the raw frame's size.
  processing::TfDepthMap& depth = st.plate_depth;
  depth.width = width_ / 2;
  depth.height = height_ / 2;
  depth.virtual_depth.assign(static_cast<std::size_t>(depth.width) * depth.height,
                             std::numeric_limits<float>::quiet_NaN());
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const PlateMarker& m : markers)
    for (const Eigen::Vector2d& q : m.quad) centre += q;
  centre /= 4.0 * static_cast<double>(markers.size());
  depth.fallback_v = plane.At(centre.x(), centre.y());
  if (!(depth.fallback_v > 1))
    return Error{"plate plane: virtual depth " + std::to_string(depth.fallback_v) +
                 " at the markers' centre (expected > 1)"};
  const PlatePlaneOptions plane_options;
  WritePlatePlaneDepth(plane, markers, plane_options, depth.width, depth.height,
                       &depth.virtual_depth);
  const processing::TfOptions tf_options;
  if (Status s = processing::RenderTotalFocus(st.frame, st.mla, depth, tf_options, &st.plate_tf);
      !s)
    return s.error();
  return RefinePlateCorners(st.plate_tf.View(), st.plate, markers, edges);
}

Status FrameLoaderOptions::Check() const {
  if (!(lambda > 0.5 && lambda <= 1.0)) return Error{"frame loader: lambda: expected in (0.5, 1]"};
  if (!(keypoint_support.radius_tf_px >= 1 && keypoint_support.radius_tf_px <= 32))
    return Error{"frame loader: keypoint_support.radius_tf_px: expected in [1, 32]"};
  return features.Check();
}

void MicroImages::Seeing(const Eigen::Vector2d& x_v, double v, const Eigen::Vector2d& c,
                         double lambda, std::vector<int>* lenses) const {
  lenses->clear();
  if (!(v > 1)) return;
  // Micro image k looks at virtual position c + (c_k - c)(lambda + v (1 -
  // lambda)) (where p_k = c_k), so the lenses that see x_v lie around
  //   q = c + (x_v - c) / (lambda + v (1 - lambda)),
  // within |q - c_k| < v r / (lambda + v (1 - lambda)) <= v r: not around
  // x_v (up to 4 lens pitches from q at the corner of `medium` at v 4.7,
  // processing/tf_kernel.h).
  const Eigen::Vector2d q = c + (x_v - c) / (lambda + v * (1 - lambda));
  int i0 = 0, j0 = 0;
  grid.Nearest(q, &i0, &j0);
  const double pitch = grid.PitchPx();
  // In lattice steps v r is at most v r / (pitch sqrt(3) / 2) rings.
  const int rings = static_cast<int>(std::ceil(v * radius_px / (pitch * 0.8))) + 1;
  for (int dj = -rings; dj <= rings; ++dj)
    for (int di = -rings; di <= rings; ++di) {
      const int i = i0 + di, j = j0 + dj;
      if (i < i_min || j < j_min || i >= i_min + ni || j >= j_min + nj) continue;
      const int k = index[static_cast<std::size_t>(j - j_min) * ni + (i - i_min)];
      if (k < 0) continue;
      const Eigen::Vector2d l = c + (centres_px[k] - c) * lambda;
      const Eigen::Vector2d p = l + (x_v - l) / v;
      if ((p - centres_px[k]).norm() < radius_px) lenses->push_back(k);
    }
}

Expected<std::unique_ptr<CalibrationFrameLoader>> CalibrationFrameLoader::Open(
    const fs::path& sequence_dir, const std::string& serial, const fs::path& mla_path,
    const PlateLayout& plate, const FrameLoaderOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  std::unique_ptr<CalibrationFrameLoader> loader(new CalibrationFrameLoader());
  loader->state_ = std::make_unique<State>();
  State& st = *loader->state_;
  st.sequence_dir = sequence_dir;
  st.serial = serial;
  st.plate = plate;
  st.options = options;
  Expected<CameraFolder> folder = DiscoverCameraFolder(layout::CameraDir(sequence_dir, serial));
  if (!folder) return folder.error();
  st.folder = *folder;
  loader->frames_ = st.folder.frames;
  const std::optional<fs::path> calib = FindCalibrationFor(sequence_dir);
  if (!calib && mla_path.empty())
    return Error{sequence_dir.string() + ": no Calibration folder beside the sequence (--mla)"};
  const fs::path mla_file = mla_path.empty() ? layout::MlaXmlPath(*calib, serial) : mla_path;
  Expected<MlaCalibration> mla = ReadMlaXml(mla_file);
  if (!mla) return mla.error();
  st.mla = *mla;
  if (calib) {
    const fs::path white_path = layout::WhiteImagePath(*calib, serial, 0);
    if (fs::exists(white_path)) {
      Expected<OwnedImage> white = ReadBmp(white_path);
      if (!white) return white.error();
      st.white = std::move(*white);
    }
  }
  if (loader->frames_.empty()) return Error{st.folder.dir.string() + ": no raw frames"};
  Expected<OwnedImage> first = ReadBmp(st.folder.dir / st.folder.frame_files[0]);
  if (!first) return first.error();
  loader->width_ = first->width;
  loader->height_ = first->height;
  const processing::MlaGrid grid =
      processing::MlaGrid::FromCalibration(st.mla, first->width, first->height);
  processing::FrameOptions frame_options;
  frame_options.lambda = options.lambda;
  frame_options.principal_point_px = options.principal_point_px;
  ConstImageView white_view;
  if (st.white.width > 0) white_view = st.white.View();
  if (Status s = processing::PrepareGeometry(white_view, first->width, first->height, grid, st.mla,
                                             frame_options, &st.frame);
      !s)
    return s.error();
  MicroImages& m = loader->micro_;
  m.grid = grid;
  m.radius_px = st.frame.radius_px;
  m.i_min = st.frame.i_min;
  m.j_min = st.frame.j_min;
  m.ni = st.frame.ni;
  m.nj = st.frame.nj;
  m.index = st.frame.lens_index;
  for (const processing::MicroImage& lens : st.frame.lenses) m.centres_px.push_back(lens.centre_px);
  return loader;
}

Expected<CalibrationFrame> CalibrationFrameLoader::Load(std::int64_t frame_number) {
  const auto start = std::chrono::steady_clock::now();
  State& st = *state_;
  const std::optional<fs::path> path = st.folder.FramePath(frame_number);
  if (!path)
    return Error{st.folder.dir.string() + ": no raw frame " + std::to_string(frame_number)};
  Expected<OwnedImage> raw = ReadBmp(*path);
  if (!raw) return raw.error();
  if (raw->width != width_ || raw->height != height_)
    return Error{path->string() + ": " + std::to_string(raw->width) + "x" +
                 std::to_string(raw->height) + ", the first frame " + std::to_string(width_) +
                 "x" + std::to_string(height_)};
  if (Status s = processing::LoadRaw(raw->View(), &st.frame); !s) return s.error();
  if (Status s = processing::EstimateVirtualDepth(st.frame, st.mla, {}, &st.depth); !s)
    return s.error();
  const processing::TfOptions tf_options;
  if (Status s = processing::VirtualDepthToTf(st.frame, st.depth, tf_options, &st.tf_depth); !s)
    return s.error();
  if (Status s = processing::RenderTotalFocus(st.frame, st.mla, st.tf_depth, tf_options, &st.tf);
      !s)
    return s.error();

  CalibrationFrame out;
  out.frame = frame_number;
  out.name = path->filename().string();
  out.tf_width = st.tf.width;
  out.tf_height = st.tf.height;
  long long with_depth = 0;
  for (const float v : st.tf_depth.virtual_depth) with_depth += std::isnan(v) ? 0 : 1;
  out.tf_depth_coverage = static_cast<double>(with_depth) / st.tf_depth.virtual_depth.size();
  if (Status s = DetectSift(st.tf.View(), st.options.features, &out.features); !s)
    return s.error();
  const int bpp = BytesPerPixel(st.tf.format);
  for (const Keypoint& k : out.features.keypoints) {
    const int x = std::clamp(static_cast<int>(std::lround(k.xy_px.x())), 0, st.tf.width - 1);
    const int y = std::clamp(static_cast<int>(std::lround(k.xy_px.y())), 0, st.tf.height - 1);
    const std::size_t at = static_cast<std::size_t>(y) * st.tf.width + x;
    out.virtual_depth.push_back(st.tf_depth.virtual_depth[at]);
    out.virtual_depth_range.push_back(VirtualDepthRange(st.tf_depth.virtual_depth, st.tf_depth.width,
                                                        st.tf_depth.height, k.xy_px,
                                                        st.options.keypoint_support.radius_tf_px));
    const std::uint8_t* px = st.tf.pixels.data() + at * bpp;
    if (bpp == 3)
      out.rgb.push_back({px[2], px[1], px[0]});
    else
      out.rgb.push_back({px[0], px[0], px[0]});
  }
  Expected<std::vector<PlateMarker>> markers = FindPlateMarkers(st.tf.View(), st.plate);
  if (!markers) return markers.error();
  // The corners are placed on the plate rendered at its plane's virtual
  // depth (plate_plane.h: the measured depth scatters most along the
  // markers' borders, and a border rendered at a wrong depth is drawn
  // shifted); where the markers hold too few measured depths for the
  // plane, on the TF image itself.
  ConstImageView corner_image = st.tf.View();
  if (!markers->empty()) {
    const PlatePlaneOptions plane_options;
    Expected<PlatePlane> plane =
        FitPlatePlane(st.tf_depth.virtual_depth, st.tf_depth.sigma_z, st.tf_depth.width,
                      st.tf_depth.height, *markers, plane_options);
    if (plane) {
      st.plate_depth.width = st.tf_depth.width;
      st.plate_depth.height = st.tf_depth.height;
      st.plate_depth.fallback_v = st.tf_depth.fallback_v;
      st.plate_depth.virtual_depth = st.tf_depth.virtual_depth;
      WritePlatePlaneDepth(*plane, *markers, plane_options, st.plate_depth.width,
                           st.plate_depth.height, &st.plate_depth.virtual_depth);
      if (Status s = processing::RenderTotalFocus(st.frame, st.mla, st.plate_depth, tf_options,
                                                  &st.plate_tf);
          !s)
        return s.error();
      corner_image = st.plate_tf.View();
    }
  }
  Expected<std::vector<PlateCorner>> corners =
      RefinePlateCorners(corner_image, st.plate, *markers);
  if (!corners) return corners.error();
  out.corners = std::move(*corners);
  for (const PlateCorner& c : out.corners) {
    const int x = std::clamp(static_cast<int>(std::lround(c.tf_px.x())), 0, st.tf.width - 1);
    const int y = std::clamp(static_cast<int>(std::lround(c.tf_px.y())), 0, st.tf.height - 1);
    out.corner_virtual_depth.push_back(
        st.tf_depth.virtual_depth[static_cast<std::size_t>(y) * st.tf.width + x]);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace lifmcr::registration
