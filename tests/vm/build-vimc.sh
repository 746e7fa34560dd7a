#!/usr/bin/env bash
# Builds the vimc module out of tree (Debian's kernels do not ship it) from linux-source-<major.minor>'s
# drivers/media/test-drivers/vimc against the installed linux-headers-<release>, and prints the .ko's
# path. The result is cached in <cache>/vimc-<release>/ and rebuilt only when missing.
# usage: build-vimc.sh <cache-dir> <kernel-release, e.g. 6.1.0-56-amd64>
set -euo pipefail
cache=$1
release=$2
die() { echo "build-vimc: $*" >&2; exit 1; }

out="$cache/vimc-$release"
if [ -f "$out/vimc.ko" ]; then echo "$out/vimc.ko"; exit 0; fi

headers="/usr/src/linux-headers-$release"
[ -f "$headers/Makefile" ] ||
  die "missing $headers: install Debian's linux-headers-$release (bash toolchains/install-deps.sh installs linux-headers-amd64)"
series=$(sed -n 's/^\([0-9]*\.[0-9]*\)\..*/\1/p' <<<"$release")
tarball="/usr/src/linux-source-$series.tar.xz"
[ -f "$tarball" ] ||
  die "missing $tarball: install Debian's linux-source-$series (bash toolchains/install-deps.sh)"

mkdir -p "$cache"
src=$(mktemp -d "$cache/vimc-build.XXXXXX")
trap 'rm -rf "$src"' EXIT
tar -xJf "$tarball" -C "$src" --strip-components=4 --wildcards "linux-source-$series/drivers/media/test-drivers/vimc/*"
[ -f "$src/vimc/vimc-core.c" ] || die "$tarball has no drivers/media/test-drivers/vimc"
# The kernel's own build system, as for any out-of-tree module; CONFIG_VIDEO_VIMC=m turns on its Makefile.
if ! make -s -C "$headers" M="$src/vimc" CONFIG_VIDEO_VIMC=m -j2 modules >"$src/build.log" 2>&1; then
  cat "$src/build.log" >&2
  die "building vimc against $headers failed (log above)"
fi
mkdir -p "$out"
cp "$src/vimc/vimc.ko" "$out/vimc.ko.tmp"
mv "$out/vimc.ko.tmp" "$out/vimc.ko"
echo "$out/vimc.ko"
