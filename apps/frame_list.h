// Frame lists on the command line: "0-9,12,20-24" (calibrate --frames,
// synth --render-frames).
#pragma once

#include "config/error.h"

#include <cstdint>
#include <set>
#include <string>

namespace lifmcr::apps {

// The frame numbers of TEXT, sorted; the error names the bad part and starts
// with OPTION ("--frames: expected ...").
Expected<std::set<std::int64_t>> ParseFrameList(const std::string& text, const std::string& option);

}  // namespace lifmcr::apps
