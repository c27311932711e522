#!/usr/bin/env bash
# Sets up (through scripts/setup.sh) when anything is missing, builds, and runs
# every test with ctest. Then the sanitizer passes:
#   parsers  the parsers' tests (every user-supplied file format) under
#            AddressSanitizer + UBSan (build-asan), the default;
#   asan     every test again under AddressSanitizer + UBSan (build-asan, the
#            whole suite through ctest; any report fails the test that made it);
#   tsan     the concurrency tests (recorder, rig controller, sync, drivers; not
#            yet the TBB pipeline, see below) under ThreadSanitizer (build-tsan);
#   fuzz     every libFuzzer target for LIFMCR_FUZZ_SECONDS (default 30) each
#            (bench/fuzz.sh, build-fuzz; needs clang and libfuzzer-14-dev).
# asan and tsan are not yet the default: on this project's 2-core machines the
# whole suite has not yet been seen to finish clean under them (README, "Tests").
# Each pass prints its wall time (build and run). Exits non-zero on any failure.
#   LIFMCR_SANITIZERS="asan tsan fuzz"  the passes to run (default: "parsers")
#   LIFMCR_SKIP_SANITIZERS=1            none of them (the Release tests only)
#   LIFMCR_SKIP_FUZZ=1                  no fuzz pass
#   LIFMCR_FUZZ_SECONDS=N               seconds per fuzz target (default 30)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LIFMCR_BUILD_DIR:-build}
jobs=$(nproc 2>/dev/null || echo 2)

scripts/setup.sh
ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" "$@"

[[ "${LIFMCR_SKIP_SANITIZERS:-0}" == 1 ]] && exit 0
passes=" ${LIFMCR_SANITIZERS:-parsers} "
[[ "${LIFMCR_SKIP_FUZZ:-0}" == 1 ]] && passes=${passes/ fuzz / }

# Every test executable of tests/CMakeLists.txt (`lifmcr_test(NAME ...)` and
# the plain `add_executable(test_...)`): ctest lists all of them, so all are built.
mapfile -t all_tests < <(sed -n -e 's/^lifmcr_test(\([A-Za-z0-9_]*\).*/\1/p' \
                                -e 's/^add_executable(\(test_[A-Za-z0-9_]*\).*/\1/p' tests/CMakeLists.txt)
# The tests whose code runs threads against each other: our own threads (grab
# loops, recorder and writer, sync, Vicon, GenTL and Aravis drivers).
# Out, with the reason:
# - test_apps_pipeline, test_apps_record_publish: processing runs on oneTBB,
#   which Debian does not build with TSan; its fork-join is invisible to TSan
#   and reported as races that no suppression can match (scripts/sanitizers/
#   tsan.supp says what would fix it).
# - test_acquisition_gv: two GigE Vision simulators answering heartbeats and
#   software triggers in real time; under TSan on a loaded 2-core machine a 5 Hz
#   recording took 144 s for 16 triggers and lost frames (no race reported).
#   test_drivers_aravis_gv runs the same driver threads under TSan.
tsan_tests=(test_acquisition_recorder test_acquisition_writer test_acquisition_cli test_sync
            test_drivers_vicon test_drivers_replay test_drivers_pool test_drivers_aravis_fake
            test_drivers_aravis_gv test_drivers_gentl)

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
# history_size=7: the longest access history, so the stack of a TBB worker's
# earlier access is restored and the libtbb suppression can match it (tsan.supp).
export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:history_size=7:suppressions=$PWD/scripts/sanitizers/tsan.supp}

if [[ $passes == *" parsers "* ]]; then
  parser_tests=(test_config test_replay_bmp test_replay_sequence test_replay_mla test_replay_vsk
                test_replay_vicon test_replay_raw_image test_lcm_types)
  start=$SECONDS
  echo "test.sh: parser tests under AddressSanitizer/UBSan in $build_dir-asan"
  sanitizer_build "$build_dir-asan" Asan "${parser_tests[@]}"
  # The binaries run directly (from the test folder, as ctest runs them), so
  # the list above is exactly what runs.
  for t in "${parser_tests[@]}"; do
    (cd "$build_dir-asan/tests" && "./$t" --gtest_brief=1) >"$build_dir-asan.$t.log" 2>&1 ||
      { tail -n 120 "$build_dir-asan.$t.log" >&2; echo "test.sh: $t failed under ASan/UBSan" >&2; exit 1; }
  done
  echo "test.sh: ${#parser_tests[@]} parser test binaries passed under ASan/UBSan: $((SECONDS - start)) s"
fi

if [[ $passes == *" asan "* ]]; then
  start=$SECONDS
  echo "test.sh: every test under AddressSanitizer/UBSan in $build_dir-asan"
  targets=("${all_tests[@]}" lifmcr)
  grep -q lifmcr_lcm_types_jar lcm_types/CMakeLists.txt && command -v javac >/dev/null &&
    targets+=(lifmcr_lcm_types_jar)
  sanitizer_build "$build_dir-asan" Asan "${targets[@]}"
  built=$((SECONDS - start))
  ctest --test-dir "$build_dir-asan" --output-on-failure -j "$jobs"
  echo "test.sh: ASan/UBSan pass: build ${built} s, tests $((SECONDS - start - built)) s"
fi

if [[ $passes == *" tsan "* ]]; then
  start=$SECONDS
  echo "test.sh: concurrency tests under ThreadSanitizer in $build_dir-tsan"
  sanitizer_build "$build_dir-tsan" Tsan "${tsan_tests[@]}" lifmcr
  built=$((SECONDS - start))
  for t in "${tsan_tests[@]}"; do
    # From the test folder, as ctest runs them.
    (cd "$build_dir-tsan/tests" && "./$t" --gtest_brief=1) >"$build_dir-tsan.$t.log" 2>&1 ||
      { tail -n 120 "$build_dir-tsan.$t.log" >&2; echo "test.sh: $t failed under TSan" >&2; exit 1; }
  done
  echo "test.sh: TSan pass (${#tsan_tests[@]} binaries): build ${built} s, tests $((SECONDS - start - built)) s"
fi

if [[ $passes == *" fuzz "* ]]; then
  start=$SECONDS
  bench/fuzz.sh "${LIFMCR_FUZZ_SECONDS:-30}"
  echo "test.sh: fuzz pass: $((SECONDS - start)) s"
fi
