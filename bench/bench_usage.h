#pragma once
// `--help` (or `-h`) of every benchmark: its usage on stdout and exit 0,
// before any work. A run renders frames, writes gigabytes or takes minutes,
// so `bench_x --help` must never start one (tests/bench/CMakeLists.txt runs
// each benchmark with --help).

#include <cstdio>
#include <cstring>

namespace lifmcr::bench {

// True, with `usage` printed on stdout, when an argument is --help or -h.
inline bool PrintedHelp(int argc, char** argv, const char* usage) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::fputs(usage, stdout);
      return true;
    }
  }
  return false;
}

}  // namespace lifmcr::bench
