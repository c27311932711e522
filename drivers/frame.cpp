#include "drivers/frame.h"

namespace lifmcr {

std::string_view ToString(FrameStatus status) {
  switch (status) {
    case FrameStatus::kOk:
      return "ok";
    case FrameStatus::kIncomplete:
      return "incomplete";
    case FrameStatus::kTimeout:
      return "timeout";
    case FrameStatus::kError:
      return "error";
  }
  return "?";
}

}  // namespace lifmcr
