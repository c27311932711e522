// A shared library that is not a whole GenTL producer: it exports GCInitLib
// and nothing else, so loading it as a .cti must fail naming what is missing.

#include <cstdint>

extern "C" __attribute__((visibility("default"))) std::int32_t GCInitLib() { return 0; }
