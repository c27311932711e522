#pragma once
// What `lifmcr info` knows about a path, as one JSON document. `--json`
// prints it as is; the text output (info_text.cpp) renders the same document,
// so both always say the same thing.
//
// Problems found on the way (a frame whose header does not match its file, a
// Vicon CSV that does not parse, an MLA centre outside the image) do not stop
// the report: they are collected in "problems" (and in the section they
// belong to) and make `lifmcr info` exit with 1.

#include "config/error.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>

namespace lifmcr::apps {

struct InfoOptions {
  // Open every raw frame's header (catches truncated files); false: only the
  // first and last frame of each camera.
  bool check_every_frame = true;
  // Called every few hundred frame headers (and at the end of a camera) with
  // the camera's serial, the frames checked and the frames to check; may be
  // empty. `lifmcr info` draws its progress line with it.
  std::function<void(const std::string& serial, std::size_t done, std::size_t total)> progress;
};

// Fails only when the path does not exist or is of no known kind.
Expected<nlohmann::json> DescribePath(const std::filesystem::path& path,
                                      const InfoOptions& options);

// Human-readable rendering of DescribePath's document.
std::string FormatInfoText(const nlohmann::json& report);

}  // namespace lifmcr::apps
