#!/usr/bin/env bash
# Builds every configuration and runs every suite: host Debug (all tests, allocation counter), host
# Release (heap guard on the shipped core), ASan+UBSan, and aarch64 under qemu. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."
if command -v ccache >/dev/null; then export CMAKE_CXX_COMPILER_LAUNCHER=ccache; fi
export LIBCAMERA_LOG_LEVELS='*:ERROR'

run_preset() {
  local preset=$1; shift
  echo "=== $preset: configure, build, test"
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset"
  ctest --preset "$preset" "$@"
}

run_preset debug
run_preset release -R '^guard_'
run_preset asan
run_preset aarch64
echo "=== all configurations passed"
