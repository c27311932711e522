#!/usr/bin/env bash
# Sets up (through scripts/setup.sh) when anything is missing, builds, and runs
# every test with ctest. Then the sanitizer passes:
#   1. every test again under AddressSanitizer + UBSan (build-asan, the whole
#      suite through ctest; any report fails the test that caused it);
#   2. the concurrency tests (pipeline, recorder, rig controller, sync,
#      drivers) under ThreadSanitizer (build-tsan);
#   3. every libFuzzer target for LIFMCR_FUZZ_SECONDS (default 30) each
#      (bench/fuzz.sh; needs clang and libfuzzer-14-dev).
# Passes 1-3 are opt-in (LIFMCR_FULL_SANITIZERS=1) until their CI time has
# been measured on a 2-core machine (not yet: see README "Tests"); by default
# the parsers' tests (every user-supplied file format) run under ASan/UBSan,
# where bad input is most likely to read out of bounds.
# Exits non-zero on any failure. Each pass prints its wall time.
#   LIFMCR_SKIP_SANITIZERS=1   skip every sanitizer pass
#   LIFMCR_FULL_SANITIZERS=1   passes 1-3 instead of the parser pass
#   LIFMCR_SKIP_FUZZ=1         skip pass 3
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LIFMCR_BUILD_DIR:-build}
jobs=$(nproc 2>/dev/null || echo 2)

scripts/setup.sh
ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" "$@"

[[ "${LIFMCR_SKIP_SANITIZERS:-0}" == 1 ]] && exit 0

# Test executables of tests/CMakeLists.txt (each `lifmcr_test(NAME ...)`).
mapfile -t all_tests < <(sed -n 's/^lifmcr_test(\([A-Za-z0-9_]*\).*/\1/p' tests/CMakeLists.txt)
# The tests whose code runs threads against each other.
tsan_tests=(test_apps_pipeline test_apps_record_publish test_acquisition_recorder
            test_acquisition_writer test_acquisition_gv test_acquisition_cli test_sync
            test_drivers_vicon test_drivers_replay test_drivers_pool test_drivers_aravis_fake
            test_drivers_aravis_gv)

sanitizer_build() {  # DIR BUILD_TYPE TARGET...
  local dir=$1 type=$2
  shift 2
  if [[ ! -f "$dir/CMakeCache.txt" ]]; then
    cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE="$type" >"$dir.configure.log" 2>&1 ||
      { cat "$dir.configure.log" >&2; exit 1; }
  fi
  cmake --build "$dir" -j "$jobs" --target "$@" >"$dir.build.log" 2>&1 ||
    { grep -v -E '^\[ *[0-9]+%\]' "$dir.build.log" | tail -n 80 >&2; exit 1; }
}

# Reports end the process with an error (exit code 1 from ctest's view).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:detect_stack_use_after_return=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/scripts/sanitizers/lsan.supp:print_suppressions=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/scripts/sanitizers/tsan.supp}

if [[ "${LIFMCR_FULL_SANITIZERS:-0}" != 1 ]]; then
  parser_tests=(test_config test_replay_bmp test_replay_sequence test_replay_mla test_replay_vsk
                test_replay_vicon test_replay_raw_image test_lcm_types)
  start=$SECONDS
  echo "test.sh: parser tests under AddressSanitizer/UBSan in $build_dir-asan"
  sanitizer_build "$build_dir-asan" Asan "${parser_tests[@]}"
  # The binaries run directly, so the list above is exactly what runs.
  for t in "${parser_tests[@]}"; do
    "$build_dir-asan/tests/$t" --gtest_brief=1 >"$build_dir-asan.$t.log" 2>&1 ||
      { cat "$build_dir-asan.$t.log" >&2; echo "test.sh: $t failed under sanitizers" >&2; exit 1; }
  done
  echo "test.sh: ${#parser_tests[@]} parser test binaries passed under sanitizers: $((SECONDS - start)) s"
  exit 0
fi

start=$SECONDS
echo "test.sh: every test under AddressSanitizer/UBSan in $build_dir-asan"
targets=("${all_tests[@]}" lifmcr)
grep -q lifmcr_lcm_types_jar lcm_types/CMakeLists.txt && command -v javac >/dev/null && targets+=(lifmcr_lcm_types_jar)
sanitizer_build "$build_dir-asan" Asan "${targets[@]}"
ctest --test-dir "$build_dir-asan" --output-on-failure -j "$jobs"
echo "test.sh: ASan/UBSan pass: $((SECONDS - start)) s"

start=$SECONDS
echo "test.sh: concurrency tests under ThreadSanitizer in $build_dir-tsan"
sanitizer_build "$build_dir-tsan" Tsan "${tsan_tests[@]}" lifmcr
for t in "${tsan_tests[@]}"; do
  "$build_dir-tsan/tests/$t" --gtest_brief=1 >"$build_dir-tsan.$t.log" 2>&1 ||
    { tail -n 120 "$build_dir-tsan.$t.log" >&2; echo "test.sh: $t failed under TSan" >&2; exit 1; }
done
echo "test.sh: TSan pass (${#tsan_tests[@]} binaries): $((SECONDS - start)) s"

if [[ "${LIFMCR_SKIP_FUZZ:-0}" != 1 ]]; then
  start=$SECONDS
  bench/fuzz.sh "${LIFMCR_FUZZ_SECONDS:-30}"
  echo "test.sh: fuzz pass: $((SECONDS - start)) s"
fi
