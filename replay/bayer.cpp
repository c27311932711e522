#include "replay/bayer.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace lifmcr {
namespace {

// OpenCV names a pattern by the second row's second and third pixels
// (imgproc "Bayer -> RGB"), GenICam by the first row's first two: RGGB
// (GenICam BayerRG) is OpenCV's BG, and so on.
int OpenCvCode(CameraPixelFormat pattern) {
  switch (pattern) {
    case CameraPixelFormat::kBayerRg8:
      return cv::COLOR_BayerBG2BGR_EA;
    case CameraPixelFormat::kBayerGr8:
      return cv::COLOR_BayerGB2BGR_EA;
    case CameraPixelFormat::kBayerGb8:
      return cv::COLOR_BayerGR2BGR_EA;
    case CameraPixelFormat::kBayerBg8:
      return cv::COLOR_BayerRG2BGR_EA;
    default:
      return -1;
  }
}

}  // namespace

bool IsBayer(CameraPixelFormat format) { return OpenCvCode(format) >= 0; }

Status DemosaicBayer(ConstImageView mosaic, CameraPixelFormat pattern, ImageView bgr) {
  const int code = OpenCvCode(pattern);
  if (code < 0)
    return Error{"demosaic: pixel format " + std::string(ToString(pattern)) +
                 " is not a Bayer mosaic"};
  if (mosaic.format != PixelFormat::kMono8 || bgr.format != PixelFormat::kBgr8 ||
      mosaic.width != bgr.width || mosaic.height != bgr.height || mosaic.width < 2 ||
      mosaic.height < 2)
    return Error{
        "demosaic: expected a Mono8 mosaic and a BGR8 image of the same size (at least 2x2)"};
  const cv::Mat src(mosaic.height, mosaic.width, CV_8UC1, const_cast<std::uint8_t*>(mosaic.data),
                    mosaic.stride_bytes);
  cv::Mat dst(bgr.height, bgr.width, CV_8UC3, bgr.data, bgr.stride_bytes);
  cv::cvtColor(src, dst, code);
  if (dst.data != bgr.data) return Error{"demosaic: internal: OpenCV reallocated the output"};
  return Status::Ok();
}

}  // namespace lifmcr
