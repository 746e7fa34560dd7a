#!/usr/bin/env bash
# Installs everything vantage needs from Debian's archive (and the npm registry for test tooling).
# Idempotent: re-running installs nothing new. Needs root or sudo.
set -euo pipefail

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: run as root or install sudo" >&2; exit 1; }
  SUDO="sudo"
fi

PACKAGES=(
  # build
  build-essential cmake ninja-build pkg-config git
  # core
  libeigen3-dev
  # tests and benchmarks
  catch2 libbenchmark-dev
  # sim_hal: ray casting, mesh loading, the default scene, scene files
  libembree-dev libassimp-dev glmark2-data libtomlplusplus-dev
  # targets: command line, images, plots; the paired mission comparison (targets/sim/tools)
  libcli11-dev libpng-dev gnuplot-nox python3
  # hal: capture and calibration
  libcamera-dev libv4l-dev libyaml-cpp-dev libssl-dev
  # aarch64 cross-build and its test runner
  g++-aarch64-linux-gnu qemu-user
  # tests/vm: Debian's kernel under QEMU with the kernel's virtual cameras (vivid, vimc). The kernel
  # images themselves are unpacked into a cache by tests/vm/fetch-kernels.sh below, not installed.
  qemu-system-x86 qemu-system-arm busybox-static cpio xz-utils socat
  # tests/vm: vimc is not in Debian's kernels; it is built out of tree from the kernel source against
  # the headers (fetch-kernels.sh takes the kernel images at exactly these headers' version)
  linux-headers-amd64 linux-source-6.1
  # tests/vm: libcamera's vimc IPA module and its data, copied into the guest
  libcamera-ipa
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ "${#missing[@]}" -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  echo "install-deps: all Debian packages present"
fi

# The machine image ships Node.js with npm (NodeSource build); Debian's npm conflicts with it, so only
# fall back to Debian's packages where no npm is present at all.
if ! command -v npm >/dev/null; then
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null
fi

# Onboard cross build (hal + vantage-onboard for aarch64): the arm64 multiarch libraries the drivers
# link against. libssl-dev is Multi-Arch: same and installs beside the host's; libyaml-cpp-dev is not (its
# arm64 package would replace the host's), so the cross build takes the arm64 runtime library and the
# host's (architecture-independent) headers. libcamera stays out of the cross build
# (VANTAGE_WITH_LIBCAMERA=OFF in the aarch64 preset).
ARM64_PACKAGES=(libyaml-cpp0.7:arm64 libssl-dev:arm64)
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  echo "install-deps: adding the arm64 architecture for the cross build's libraries"
  $SUDO dpkg --add-architecture arm64
  $SUDO apt-get update -qq
fi
missing_arm64=()
for p in "${ARM64_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing_arm64+=("$p")
done
if [ "${#missing_arm64[@]}" -gt 0 ]; then
  echo "install-deps: installing ${missing_arm64[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing_arm64[@]}" >/dev/null
fi

# The MAVLink test peer (tests/mavlink_peer): node-mavlink and mavlink-mappings at the versions its
# package-lock.json pins.
bash "$(dirname "$0")/../tests/mavlink_peer/install.sh"

# The VM tests' kernels (tests/vm): Debian's linux-image for amd64 and arm64 and arm64's busybox-static,
# downloaded with apt-get and unpacked into /var/cache/vantage-vm (not installed on this machine).
bash "$(dirname "$0")/../tests/vm/fetch-kernels.sh"
