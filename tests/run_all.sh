#!/usr/bin/env bash
# Builds the configurations CI checks and runs every suite in at least one of them: host Release (what
# ships, the guards, the integration and VM tests), ASan+UBSan with assertions (every host suite), and
# aarch64 under qemu (the core and hal suites with the counting allocator). Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."
if command -v ccache >/dev/null; then export CMAKE_CXX_COMPILER_LAUNCHER=ccache; fi
export LIBCAMERA_LOG_LEVELS='*:ERROR'

# run_preset <preset> [--target T ...] [-- ctest arguments...]
run_preset() {
  local preset=$1; shift
  local build_args=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do build_args+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  echo "=== $preset: configure, build, test"
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" "${build_args[@]}"
  ctest --preset "$preset" "$@"
}

# No Debug step: everything it checked is checked elsewhere, and it was a third of CI's time (438 s of
# build and 137 s of tests in session 40). ASan builds with assertions on (no NDEBUG), so Eigen's size and
# index checks still run on every host suite; the counting allocator behind REQUIRE_NO_ALLOCATION runs in
# aarch64's core and hal suites (every file that uses it) and in Release's guard.
# Release builds what ships, what the guards read, integration_tests and the VM tests' programs, and runs
# those (the other suites run in ASan and aarch64). ASan runs the integration test's visible cases too.
run_preset release --target vantage_executables vantage_guard_inputs integration_tests vantage_vm_inputs -- \
  -R '^guard_|^integration_|^vm_'
run_preset asan
run_preset aarch64
echo "=== all configurations passed"
