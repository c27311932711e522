// Rig file (strict YAML reader); an accepted rig is written and read back.

#include "config/rig_config.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  // A base folder that does not exist: the loader's file checks fail
  // cleanly, everything before them runs.
  Expected<RigConfig> rig =
      ParseRigConfig(fuzz::Text(data, size), "/nonexistent-lifmcr-fuzz", "fuzz.yaml");
  if (!rig) return 0;
  (void)ParseRigConfig(FormatRigConfig(*rig), "/nonexistent-lifmcr-fuzz", "again.yaml");
  return 0;
}
