#include "apps/commands.h"

#include <CLI/CLI.hpp>
namespace lifmcr::apps {
CommandRun AddViconCommand(CLI::App&) {
  return [] { return 0; };
}
}  // namespace lifmcr::apps
