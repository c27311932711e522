#include "registration/map/reference_map.h"

#include "registration/features/features.h"
#include "registration/map/poses_csv.h"

#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <unordered_map>

namespace lifmcr::registration {
namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'L', 'F', 'M', 'C', 'R', 'M', 'A', 'P'};
constexpr std::uint32_t kVersion = 1;
constexpr const char* kSerialComment = "# lifmcr serial: ";

template <typename T>
void Put(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}
template <typename T>
bool Get(std::istream& in, T* value) {
  return static_cast<bool>(in.read(reinterpret_cast<char*>(value), sizeof(T)));
}

Status WriteFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) return Error{path.string() + ": could not write"};
  return Status::Ok();
}

std::string Format(const char* fmt, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

std::string CamerasTxt(const MapCamera& c) {
  return "# Camera list with one line of data per camera:\n"
         "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
         "# TF pinhole of the totally focused grid (lifmcr registration/map/reference_map.h)\n" +
         std::string(kSerialComment) + c.serial + "\n" +
         Format("1 PINHOLE %d %d %.9f %.9f %.9f %.9f\n", c.width_px, c.height_px, c.focal_px,
                c.focal_px, c.principal_point_px.x(), c.principal_point_px.y());
}

std::string ImagesTxt(const ReferenceMap& map) {
  std::string text =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "# Poses are c0_from_w0 (COLMAP cam_from_world), translations in mm.\n";
  for (const MapImage& image : map.images) {
    const Pose c0_from_w0 = image.w0_from_c0.inverse();
    const Eigen::Quaterniond q(c0_from_w0.linear());
    const Eigen::Vector3d t = c0_from_w0.translation();
    text += Format("%d %.12f %.12f %.12f %.12f %.6f %.6f %.6f 1 ", image.image_id, q.w(), q.x(),
                   q.y(), q.z(), t.x(), t.y(), t.z()) +
            image.name + "\n";
    std::string line;
    for (const MapKeypoint& k : image.keypoints) {
      if (!line.empty()) line += ' ';
      line += Format("%.4f %.4f %lld", k.pinhole_px.x(), k.pinhole_px.y(),
                     static_cast<long long>(k.point_id));
    }
    text += line + "\n";
  }
  return text;
}

std::string Points3DTxt(const ReferenceMap& map) {
  std::string text =
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      "# X, Y, Z in mm in the world frame w0.\n";
  for (const MapPoint& p : map.points) {
    text += Format("%lld %.6f %.6f %.6f %d %d %d %.6f", static_cast<long long>(p.id),
                   p.p_in_w0_mm.x(), p.p_in_w0_mm.y(), p.p_in_w0_mm.z(), p.rgb[0], p.rgb[1],
                   p.rgb[2], p.error_px);
    for (const TrackElement& t : p.track) text += Format(" %d %d", t.image_id, t.keypoint);
    text += "\n";
  }
  return text;
}

std::string PointsPly(const ReferenceMap& map) {
  std::string text = "ply\nformat ascii 1.0\ncomment lifmcr reference map, mm, world frame w0\n";
  text += "element vertex " + std::to_string(map.points.size()) + "\n";
  text +=
      "property float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      "property float sigma_mm\nend_header\n";
  for (const MapPoint& p : map.points)
    text += Format("%.4f %.4f %.4f %d %d %d %.4f\n", p.p_in_w0_mm.x(), p.p_in_w0_mm.y(),
                   p.p_in_w0_mm.z(), p.rgb[0], p.rgb[1], p.rgb[2], p.sigma_mm.maxCoeff());
  return text;
}

Status WriteDescriptors(const fs::path& path, const ReferenceMap& map) {
  std::ofstream out(path, std::ios::binary);
  out.write(kMagic, sizeof(kMagic));
  Put(out, kVersion);
  Put(out, static_cast<std::uint32_t>(kDescriptorSize));
  Put(out, static_cast<std::uint64_t>(map.points.size()));
  std::vector<float> zero(kDescriptorSize, 0.f);
  for (const MapPoint& p : map.points) {
    if (!p.descriptor.empty() && p.descriptor.size() != static_cast<std::size_t>(kDescriptorSize))
      return Error{path.string() + ": point " + std::to_string(p.id) + " has a descriptor of " +
                   std::to_string(p.descriptor.size()) + " floats, expected " +
                   std::to_string(kDescriptorSize)};
    Put(out, static_cast<std::int64_t>(p.id));
    for (int k = 0; k < 3; ++k) Put(out, p.sigma_mm[k]);
    const std::vector<float>& d = p.descriptor.empty() ? zero : p.descriptor;
    out.write(reinterpret_cast<const char*>(d.data()), kDescriptorSize * sizeof(float));
  }
  std::uint64_t observations = 0;
  for (const MapPoint& p : map.points) observations += p.track.size();
  Put(out, observations);
  std::unordered_map<int, const MapImage*> images;
  for (const MapImage& image : map.images) images[image.image_id] = &image;
  for (const MapPoint& p : map.points)
    for (const TrackElement& t : p.track) {
      const auto it = images.find(t.image_id);
      if (it == images.end() || t.keypoint < 0 ||
          t.keypoint >= static_cast<int>(it->second->keypoints.size()))
        return Error{path.string() + ": point " + std::to_string(p.id) +
                     " is observed by image " + std::to_string(t.image_id) + " keypoint " +
                     std::to_string(t.keypoint) + ", which the map does not hold"};
      const MapKeypoint& k = it->second->keypoints[t.keypoint];
      Put(out, static_cast<std::int64_t>(p.id));
      Put(out, static_cast<std::int32_t>(t.image_id));
      Put(out, static_cast<std::int32_t>(t.keypoint));
      Put(out, k.tf_px.x());
      Put(out, k.tf_px.y());
      Put(out, k.virtual_depth);
    }
  if (!out) return Error{path.string() + ": could not write"};
  return Status::Ok();
}

// Non-comment lines of a COLMAP text file with their 1-based line numbers.
Expected<std::vector<std::pair<int, std::string>>> DataLines(const fs::path& path,
                                                             std::string* serial = nullptr) {
  std::ifstream in(path);
  if (!in) return Error{path.string() + ": cannot open"};
  std::vector<std::pair<int, std::string>> lines;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (serial && line.rfind(kSerialComment, 0) == 0)
      *serial = line.substr(std::strlen(kSerialComment));
    if (line.empty() || line[0] == '#') {
      // images.txt: an image without keypoints has an empty second line.
      if (line.empty()) lines.emplace_back(n, line);
      continue;
    }
    lines.emplace_back(n, line);
  }
  return lines;
}

Error LineError(const fs::path& path, int line, const std::string& what) {
  return MakeError(path.string(), line, 0, what);
}

}  // namespace

Status WriteReferenceMap(const fs::path& dir, const ReferenceMap& map) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error{dir.string() + ": " + ec.message()};
  if (Status s = WriteFile(dir / "cameras.txt", CamerasTxt(map.camera)); !s) return s;
  if (Status s = WriteFile(dir / "images.txt", ImagesTxt(map)); !s) return s;
  if (Status s = WriteFile(dir / "points3D.txt", Points3DTxt(map)); !s) return s;
  if (Status s = WriteFile(dir / "points.ply", PointsPly(map)); !s) return s;
  if (Status s = WriteDescriptors(dir / "descriptors.bin", map); !s) return s;
  std::vector<FramePose> poses;
  for (const MapImage& image : map.images)
    poses.push_back(FramePose{image.frame, image.vicon_frame, image.w0_from_c0});
  return WritePosesCsv(dir / ("poses_" + map.camera.serial + ".csv"), poses);
}

Expected<ReferenceMap> ReadReferenceMap(const fs::path& dir) {
  ReferenceMap map;
  // cameras.txt
  {
    const fs::path path = dir / "cameras.txt";
    auto lines = DataLines(path, &map.camera.serial);
    if (!lines) return lines.error();
    bool found = false;
    for (const auto& [n, line] : *lines) {
      if (line.empty()) continue;
      std::istringstream s(line);
      int id = 0;
      std::string model;
      double fx = 0, fy = 0, cx = 0, cy = 0;
      if (!(s >> id >> model >> map.camera.width_px >> map.camera.height_px >> fx >> fy >> cx >>
            cy) ||
          model != "PINHOLE" || std::abs(fx - fy) > 1e-6 * fx)
        return LineError(path, n, "expected `1 PINHOLE W H f f cx cy`");
      map.camera.focal_px = fx;
      map.camera.principal_point_px = {cx, cy};
      found = true;
    }
    if (!found) return Error{path.string() + ": no camera"};
  }
  // images.txt: two lines per image.
  std::unordered_map<int, std::size_t> image_index;
  {
    const fs::path path = dir / "images.txt";
    auto lines = DataLines(path);
    if (!lines) return lines.error();
    std::vector<std::pair<int, std::string>> data;
    for (std::size_t k = 0; k < lines->size(); ++k) {
      // An empty line counts only as the keypoint line of an image.
      if ((*lines)[k].second.empty() && data.size() % 2 == 0) continue;
      data.push_back((*lines)[k]);
    }
    if (data.size() % 2 != 0)
      return LineError(path, data.back().first, "expected a keypoint line after the image line");
    for (std::size_t k = 0; k < data.size(); k += 2) {
      MapImage image;
      std::istringstream s(data[k].second);
      double qw, qx, qy, qz, tx, ty, tz;
      int camera = 0;
      if (!(s >> image.image_id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> camera >>
            image.name))
        return LineError(path, data[k].first,
                         "expected `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`");
      Pose c0_from_w0 = Pose::Identity();
      c0_from_w0.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
      c0_from_w0.translation() = Eigen::Vector3d(tx, ty, tz);
      image.w0_from_c0 = c0_from_w0.inverse();
      std::istringstream p(data[k + 1].second);
      double x, y;
      long long id;
      while (p >> x >> y >> id) {
        MapKeypoint kp;
        kp.pinhole_px = {x, y};
        kp.point_id = id;
        image.keypoints.push_back(kp);
      }
      if (!p.eof())
        return LineError(path, data[k + 1].first, "expected triples `X Y POINT3D_ID`");
      image_index[image.image_id] = map.images.size();
      map.images.push_back(std::move(image));
    }
  }
  // points3D.txt
  std::unordered_map<std::int64_t, std::size_t> point_index;
  {
    const fs::path path = dir / "points3D.txt";
    auto lines = DataLines(path);
    if (!lines) return lines.error();
    for (const auto& [n, line] : *lines) {
      if (line.empty()) continue;
      std::istringstream s(line);
      MapPoint p;
      long long id;
      int r, g, b;
      if (!(s >> id >> p.p_in_w0_mm.x() >> p.p_in_w0_mm.y() >> p.p_in_w0_mm.z() >> r >> g >> b >>
            p.error_px))
        return LineError(path, n, "expected `POINT3D_ID X Y Z R G B ERROR TRACK[]`");
      p.id = id;
      p.rgb = {static_cast<std::uint8_t>(r), static_cast<std::uint8_t>(g),
               static_cast<std::uint8_t>(b)};
      TrackElement t;
      while (s >> t.image_id >> t.keypoint) {
        if (!image_index.count(t.image_id))
          return LineError(path, n, "track names image " + std::to_string(t.image_id) +
                                        ", which images.txt does not hold");
        p.track.push_back(t);
      }
      if (!s.eof()) return LineError(path, n, "expected pairs `IMAGE_ID POINT2D_IDX`");
      point_index[p.id] = map.points.size();
      map.points.push_back(std::move(p));
    }
  }
  // descriptors.bin
  {
    const fs::path path = dir / "descriptors.bin";
    std::ifstream in(path, std::ios::binary);
    if (!in) return Error{path.string() + ": cannot open"};
    char magic[8];
    std::uint32_t version = 0, size = 0;
    std::uint64_t count = 0;
    if (!in.read(magic, 8) || std::memcmp(magic, kMagic, 8) != 0 || !Get(in, &version) ||
        version != kVersion || !Get(in, &size) || size != kDescriptorSize || !Get(in, &count))
      return Error{path.string() + ": expected the header LFMCRMAP, version 1, 128"};
    if (count != map.points.size())
      return Error{path.string() + ": holds " + std::to_string(count) + " points, points3D.txt " +
                   std::to_string(map.points.size())};
    for (std::uint64_t k = 0; k < count; ++k) {
      std::int64_t id = 0;
      Eigen::Vector3f sigma;
      std::vector<float> d(kDescriptorSize);
      if (!Get(in, &id) || !Get(in, &sigma[0]) || !Get(in, &sigma[1]) || !Get(in, &sigma[2]) ||
          !in.read(reinterpret_cast<char*>(d.data()), kDescriptorSize * sizeof(float)))
        return Error{path.string() + ": ends inside point record " + std::to_string(k)};
      const auto it = point_index.find(id);
      if (it == point_index.end())
        return Error{path.string() + ": point " + std::to_string(id) + " is not in points3D.txt"};
      map.points[it->second].sigma_mm = sigma;
      map.points[it->second].descriptor = std::move(d);
    }
    std::uint64_t observations = 0;
    if (!Get(in, &observations)) return Error{path.string() + ": ends before the observations"};
    for (std::uint64_t k = 0; k < observations; ++k) {
      std::int64_t id;
      std::int32_t image_id, keypoint;
      float x, y, v;
      if (!Get(in, &id) || !Get(in, &image_id) || !Get(in, &keypoint) || !Get(in, &x) ||
          !Get(in, &y) || !Get(in, &v))
        return Error{path.string() + ": ends inside observation " + std::to_string(k)};
      const auto it = image_index.find(image_id);
      if (it == image_index.end() || keypoint < 0 ||
          keypoint >= static_cast<int>(map.images[it->second].keypoints.size()))
        return Error{path.string() + ": observation " + std::to_string(k) + " names image " +
                     std::to_string(image_id) + " keypoint " + std::to_string(keypoint) +
                     ", which images.txt does not hold"};
      MapKeypoint& kp = map.images[it->second].keypoints[keypoint];
      kp.tf_px = {x, y};
      kp.virtual_depth = v;
    }
  }
  // poses_<serial>.csv: frame and Vicon frame of each image, in order.
  {
    const fs::path path = dir / ("poses_" + map.camera.serial + ".csv");
    Expected<std::vector<FramePose>> poses = ReadPosesCsv(path);
    if (!poses) return poses.error();
    if (poses->size() != map.images.size())
      return Error{path.string() + ": " + std::to_string(poses->size()) + " rows, images.txt " +
                   std::to_string(map.images.size()) + " images"};
    for (std::size_t k = 0; k < poses->size(); ++k) {
      map.images[k].frame = (*poses)[k].frame;
      map.images[k].vicon_frame = (*poses)[k].vicon_frame;
    }
  }
  return map;
}

}  // namespace lifmcr::registration
