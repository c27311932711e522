#include "apps/registration_args.h"

#include <CLI/CLI.hpp>

namespace lifmcr::apps {

Status RegistrationArgs::Check() const {
  if (reference.empty() && !extrinsics_csv.empty())
    return Error{"--extrinsics-csv needs --reference MAP_DIR"};
  if (reference.empty() && rigid_mount) return Error{"--rigid-mount needs --reference MAP_DIR"};
  if (reference.empty() && relocalise_every_frame)
    return Error{"--relocalise-every-frame needs --reference MAP_DIR"};
  return Status::Ok();
}

void AddRegistrationOptions(CLI::App& app, RegistrationArgs* args,
                            const std::string& reference_help) {
  app.add_option("--reference", args->reference, reference_help)->check(CLI::ExistingDirectory);
  app.add_option("--intrinsics", args->intrinsics,
                 "cameras.yaml / intrinsics.yaml files (metric depth; registration)")
      ->check(CLI::ExistingFile);
  app.add_option("--extrinsics-csv", args->extrinsics_csv,
                 "With --reference: every published c0_from_cx as registration.csv rows");
}

}  // namespace lifmcr::apps
