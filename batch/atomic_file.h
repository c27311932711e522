#pragma once
// Files a reader must see whole or not at all (the plan, each manifest
// entry): written to a temporary file in the same folder, fsync'ed, renamed
// over the final name (rename(2) within one file system is atomic) and the
// folder fsync'ed, so after a crash or a SIGKILL at any point the name holds
// either the old content or the new one, never a part.

#include "config/error.h"

#include <filesystem>
#include <string_view>

namespace lifmcr::batch {

// Writes `content` to `path` as above; creates the parent folders. The
// temporary file is ".<name>.tmp.<pid>" beside `path` and is removed on failure.
Status WriteFileAtomically(const std::filesystem::path& path, std::string_view content);

// The whole content of a regular file, or an error naming it.
Expected<std::string> ReadWholeFile(const std::filesystem::path& path);

}  // namespace lifmcr::batch
