#!/usr/bin/env bash
# Sets up (through scripts/setup.sh) when anything is missing, builds, and runs
# every test with ctest. Then the parsers' tests (every user-supplied file
# format) run again under AddressSanitizer and UBSan, where bad input is most
# likely to read out of bounds. Exits non-zero on any failure.
#   LIFMCR_SKIP_SANITIZERS=1  skip the sanitizer pass
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LIFMCR_BUILD_DIR:-build}
jobs=$(nproc 2>/dev/null || echo 2)

scripts/setup.sh
ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" "$@"

if [[ "${LIFMCR_SKIP_SANITIZERS:-0}" != 1 ]]; then
  asan_dir=${build_dir}-asan
  parser_tests=(test_config test_replay_bmp test_replay_sequence test_replay_mla test_replay_vsk
                test_replay_vicon)
  echo "test.sh: parser tests under AddressSanitizer/UBSan in $asan_dir"
  if [[ ! -f "$asan_dir/CMakeCache.txt" ]]; then
    cmake -S . -B "$asan_dir" -DCMAKE_BUILD_TYPE=Asan >"$asan_dir.configure.log" 2>&1 ||
      { cat "$asan_dir.configure.log" >&2; exit 1; }
  fi
  cmake --build "$asan_dir" -j "$jobs" --target "${parser_tests[@]}" >"$asan_dir.build.log" 2>&1 ||
    { tail -n 80 "$asan_dir.build.log" >&2; exit 1; }
  # The binaries run directly, so the list above is exactly what runs.
  for t in "${parser_tests[@]}"; do
    "$asan_dir/tests/$t" --gtest_brief=1 >"$asan_dir.$t.log" 2>&1 ||
      { cat "$asan_dir.$t.log" >&2; echo "test.sh: $t failed under sanitizers" >&2; exit 1; }
  done
  echo "test.sh: ${#parser_tests[@]} parser test binaries passed under sanitizers"
fi
