#!/usr/bin/env bash
# Puts Debian's own kernels for the VM tests (tests/vm) into a cache, without installing them on this
# machine: linux-image for amd64 and arm64 at exactly the version of the installed linux-headers-amd64
# (vimc is built out of tree against those headers, so image and headers must agree), and arm64's
# busybox-static for the arm guest. Called by toolchains/install-deps.sh; idempotent.
#
# Layout: $VANTAGE_VM_CACHE (default /var/cache/vantage-vm)/
#   linux-image-<abi>-<arch>_<version>/{boot,lib/modules/<release>/kernel/drivers/media}
#   amd64 -> linux-image-...-amd64_...   arm64 -> linux-image-...-arm64_...   (what tests/vm boots)
#   busybox-arm64/bin/busybox
set -euo pipefail

CACHE=${VANTAGE_VM_CACHE:-/var/cache/vantage-vm}
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

log() { echo "fetch-kernels: $*"; }
die() { echo "fetch-kernels: $*" >&2; exit 1; }

# The kernel ABI and version come from the installed headers metapackage, e.g.
# "linux-headers-6.1.0-56-amd64 (= 6.1.192-2)".
read_headers_version() {
  local headers_dep
  headers_dep=$(dpkg-query -W -f='${Depends}' linux-headers-amd64 2>/dev/null) ||
    die "linux-headers-amd64 is not installed (run: bash toolchains/install-deps.sh)"
  abi=$(sed -n 's/^linux-headers-\([0-9][^ ]*\)-amd64 (= .*$/\1/p' <<<"$headers_dep")
  version=$(sed -n 's/^linux-headers-[^ ]* (= \([^)]*\))$/\1/p' <<<"$headers_dep")
  [ -n "$abi" ] && [ -n "$version" ] || die "cannot read the kernel ABI from linux-headers-amd64's Depends: '$headers_dep'"
}
read_headers_version

if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  log "adding the arm64 architecture (for Debian's arm64 kernel and busybox)"
  $SUDO dpkg --add-architecture arm64
  $SUDO apt-get update -qq
fi

$SUDO mkdir -p "$CACHE"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

download() {  # download <package:arch=version>: into $tmp; one apt-get update and retry if the lists are old
  (cd "$tmp" && apt-get download -q "$1" >/dev/null 2>&1) && return 0
  $SUDO apt-get update -qq
  (cd "$tmp" && apt-get download -q "$1" >/dev/null 2>&1)
}

# The archive keeps only the newest kernel of a series: when the installed headers' kernel is gone from
# it, move the headers (and so vimc's build) to the newest kernel, whose image can then be fetched.
if [ ! -f "$CACHE/linux-image-$abi-amd64_$version/.complete" ] &&
   ! (cd "$tmp" && apt-get download -q --print-uris "linux-image-$abi-amd64:amd64=$version" >/dev/null 2>&1); then
  $SUDO apt-get update -qq
  if ! (cd "$tmp" && apt-get download -q --print-uris "linux-image-$abi-amd64:amd64=$version" >/dev/null 2>&1); then
    log "linux-image-$abi-amd64=$version is no longer in the archive: upgrading linux-headers-amd64"
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends linux-headers-amd64 >/dev/null
    read_headers_version
  fi
fi

for arch in amd64 arm64; do
  pkg="linux-image-$abi-$arch"
  dir="$CACHE/${pkg}_$version"
  if [ ! -f "$dir/.complete" ]; then
    log "unpacking $pkg=$version into $dir"
    download "$pkg:$arch=$version" || die "cannot download $pkg:$arch=$version from Debian's archive"
    $SUDO rm -rf "$dir"
    $SUDO mkdir -p "$dir"
    # Only the kernel and the media modules: the VM tests need nothing else, and it saves ~400 MB.
    dpkg-deb --fsys-tarfile "$tmp"/"${pkg}"_*.deb |
      $SUDO tar -x -C "$dir" --wildcards './boot/vmlinuz-*' './boot/config-*' \
        './lib/modules/*/kernel/drivers/media/*' './lib/modules/*/modules.builtin'
    rm -f "$tmp"/*.deb
    $SUDO touch "$dir/.complete"
  fi
  $SUDO ln -sfn "$(basename "$dir")" "$CACHE/$arch"
done

if [ ! -x "$CACHE/busybox-arm64/bin/busybox" ]; then
  log "unpacking busybox-static:arm64 into $CACHE/busybox-arm64"
  download "busybox-static:arm64" || die "cannot download busybox-static:arm64 from Debian's archive"
  $SUDO rm -rf "$CACHE/busybox-arm64"
  $SUDO mkdir -p "$CACHE/busybox-arm64"
  dpkg-deb --fsys-tarfile "$tmp"/busybox-static_*_arm64.deb | $SUDO tar -x -C "$CACHE/busybox-arm64" ./bin/busybox
fi
log "kernels $abi ($version) for amd64 and arm64 in $CACHE"
