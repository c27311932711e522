#include "replay/synth/gt_images.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <system_error>

namespace lifmcr::synth {
namespace {

Status EnsureParent(const std::filesystem::path& path) {
  std::error_code error;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), error);
  if (error) return MakeErrorAt(path.string(), "/", "cannot create its folder: " + error.message());
  return Status::Ok();
}

}  // namespace

// cv::haveImageWriter looks the extension up in OpenCV's codec registry, a
// function-local static of libopencv_imgcodecs built by its first user. Built
// here, in the thread that then starts the writers, the registry's construction
// is ordered before them by the thread hand-over. Left to the first imwrite in
// a TBB worker, it was ordered only by the static's guard, read inline in
// uninstrumented OpenCV code, which ThreadSanitizer cannot see: it reported
// the main thread's read of the BMP encoder's description (copied while
// looking up ".tiff") as racing with the worker's construction of it.
Status CheckImageWriters() {
  for (const char* extension : {".tiff", ".png"}) {
    if (!cv::haveImageWriter(extension))
      return Error{std::string("this OpenCV build has no ") + extension +
                   " image writer (lifmcr synth writes its ground truth with it)"};
  }
  return Status::Ok();
}

Status WriteFloatTiff(const std::filesystem::path& path, int width, int height,
                      const std::vector<float>& values) {
  if (width <= 0 || height <= 0 || values.size() != static_cast<std::size_t>(width) * height)
    return MakeErrorAt(path.string(), "/", "float map size does not match width x height");
  if (Status s = EnsureParent(path); !s) return s;
  // cv::Mat over the caller's buffer: no copy (imwrite only reads it).
  const cv::Mat map(height, width, CV_32FC1, const_cast<float*>(values.data()));
  try {
    if (!cv::imwrite(path.string(), map))
      return MakeErrorAt(path.string(), "/", "OpenCV could not write the float32 TIFF");
  } catch (const cv::Exception& e) {
    return MakeErrorAt(path.string(), "/", std::string("OpenCV: ") + e.what());
  }
  return Status::Ok();
}

Expected<std::vector<float>> ReadFloatTiff(const std::filesystem::path& path, int* width,
                                           int* height) {
  cv::Mat map;
  try {
    map = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return MakeErrorAt(path.string(), "/", std::string("OpenCV: ") + e.what());
  }
  if (map.empty()) return MakeErrorAt(path.string(), "/", "cannot read the TIFF");
  if (map.type() != CV_32FC1)
    return MakeErrorAt(path.string(), "/", "expected a one-channel float32 TIFF");
  *width = map.cols;
  *height = map.rows;
  std::vector<float> values(static_cast<std::size_t>(map.rows) * map.cols);
  for (int y = 0; y < map.rows; ++y)
    std::copy(map.ptr<float>(y), map.ptr<float>(y) + map.cols, values.begin() + y * map.cols);
  return values;
}

Status WritePng(const std::filesystem::path& path, ConstImageView image) {
  if (Status s = EnsureParent(path); !s) return s;
  const int type = image.format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  const cv::Mat mat(image.height, image.width, type, const_cast<std::uint8_t*>(image.data),
                    image.stride_bytes);
  try {
    if (!cv::imwrite(path.string(), mat))
      return MakeErrorAt(path.string(), "/", "OpenCV could not write the PNG");
  } catch (const cv::Exception& e) {
    return MakeErrorAt(path.string(), "/", std::string("OpenCV: ") + e.what());
  }
  return Status::Ok();
}

}  // namespace lifmcr::synth
