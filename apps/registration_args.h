#pragma once
// The live-registration options of `lifmcr replay` and `lifmcr record
// --publish` (--reference, --intrinsics, --extrinsics-csv), registered once
// so both commands read them alike (apps/pipeline/live_registration.h runs them).

#include "config/error.h"

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace lifmcr::apps {

struct RegistrationArgs {
  std::string reference;                // MAP_DIR; empty: no live registration
  std::vector<std::string> intrinsics;  // cameras.yaml / intrinsics.yaml files
  std::string extrinsics_csv;           // FILE; needs reference
  bool rigid_mount = false;             // change detection (replay's --rigid-mount)
  // Relocalise every frame instead of tracking (replay's --relocalise-every-frame).
  bool relocalise_every_frame = false;
  // --extrinsics-csv, --rigid-mount or --relocalise-every-frame without
  // --reference is a usage error
  // (the message names the option).
  Status Check() const;
};

// Adds --reference (its help: `reference_help`), --intrinsics and
// --extrinsics-csv to `app`, writing into `args` (which must outlive it).
void AddRegistrationOptions(CLI::App& app, RegistrationArgs* args,
                            const std::string& reference_help);

}  // namespace lifmcr::apps
