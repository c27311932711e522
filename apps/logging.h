#pragma once
// The one logger of a `lifmcr` run (spdlog's default logger), configured by
// the command line: --log-level (trace, debug, info, warn, error, off;
// default warn) and --log-file (default: stderr). The libraries log through
// it only what an operator needs afterwards: the configuration in force, a
// device lost and back, drops with their cause. Nothing per frame.

#include "config/error.h"

#include <string>

namespace lifmcr::apps {

Status ConfigureLogging(const std::string& level, const std::string& file);

}  // namespace lifmcr::apps
