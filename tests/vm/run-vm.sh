#!/usr/bin/env bash
# Boots Debian's kernel in QEMU (TCG, no network) with a small initramfs: busybox-static as /init, the
# media modules a test needs, the test programs and their shared libraries. Reads PASS/FAIL lines from
# the serial console and passes when the guest reports exit 0, at least --min-pass PASS lines and no
# FAIL line. The VM is killed at --timeout and the console log is printed on any failure.
#
# usage: run-vm.sh --arch x86_64|aarch64 --work DIR --cache DIR [--modules "vivid[:p=v,...] ..."]
#                  --bin FILE... [--data FILE...] --run "guest shell command" [--expect-node /dev/X...]
#                  [--libcamera] [--timeout S] [--min-pass N] [--serial2-socket PATH] [--console-copy FILE]
# --serial2-socket gives the guest a second UART, /dev/ttyMAV0, connected to that listening unix socket.
# --work is this test's scratch directory; --cache is shared by all VM tests of a build (vmlinux,
# vimc.ko, the base initramfs per module set). In the guest, --bin files are in /opt/vantage/bin and
# --data files in /opt/vantage; --run executes in /opt/vantage.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
KCACHE=${VANTAGE_VM_CACHE:-/var/cache/vantage-vm}

die() { echo "run-vm: $*" >&2; exit 2; }

arch=x86_64 work= cache= run_cmd= timeout_s=180 min_pass=1 libcamera=0 serial2= console_copy=
modules=() bins=() data=() nodes=()
while [ $# -gt 0 ]; do
  case $1 in
    --arch) arch=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --cache) cache=$2; shift 2 ;;
    --modules) read -r -a modules <<<"$2"; shift 2 ;;
    --bin) bins+=("$2"); shift 2 ;;
    --data) data+=("$2"); shift 2 ;;
    --run) run_cmd=$2; shift 2 ;;
    --expect-node) nodes+=("$2"); shift 2 ;;
    --libcamera) libcamera=1; shift ;;
    --timeout) timeout_s=$2; shift 2 ;;
    --min-pass) min_pass=$2; shift 2 ;;
    --serial2-socket) serial2=$2; shift 2 ;;
    --console-copy) console_copy=$2; shift 2 ;;
    *) die "unknown argument '$1' (see the usage at the top of $0)" ;;
  esac
done
[ -n "$work" ] && [ -n "$cache" ] && [ -n "$run_cmd" ] || die "--work, --cache and --run are required"

# ---- what this architecture needs, and what to install when it is missing
case $arch in
  x86_64)
    qemu=qemu-system-x86_64 qemu_pkg=qemu-system-x86 kdir="$KCACHE/amd64" triplet=x86_64-linux-gnu
    busybox=/bin/busybox console=ttyS0 strip=strip
    libdirs=(/lib/x86_64-linux-gnu /usr/lib/x86_64-linux-gnu /lib64 /usr/lib) ;;
  aarch64)
    qemu=qemu-system-aarch64 qemu_pkg=qemu-system-arm kdir="$KCACHE/arm64" triplet=aarch64-linux-gnu
    busybox="$KCACHE/busybox-arm64/bin/busybox" console=ttyAMA0 strip=aarch64-linux-gnu-strip
    libdirs=(/usr/aarch64-linux-gnu/lib /usr/lib/aarch64-linux-gnu /lib/aarch64-linux-gnu) ;;
  *) die "--arch must be x86_64 or aarch64, not '$arch'" ;;
esac
command -v "$qemu" >/dev/null ||
  die "$qemu not found: install Debian's $qemu_pkg (bash toolchains/install-deps.sh)"
for tool in cpio readelf timeout flock "$strip"; do
  command -v "$tool" >/dev/null || die "$tool not found: run bash toolchains/install-deps.sh"
done
vmlinuz=$(ls "$kdir"/boot/vmlinuz-* 2>/dev/null | head -n 1 || true)
[ -n "$vmlinuz" ] ||
  die "no Debian kernel in $kdir: run bash toolchains/install-deps.sh (it downloads linux-image-<abi>-${kdir##*/} with tests/vm/fetch-kernels.sh and unpacks it there)"
release=${vmlinuz##*/vmlinuz-}
kmods="$kdir/lib/modules/$release/kernel"
[ -x "$busybox" ] || die "no busybox at $busybox: run bash toolchains/install-deps.sh (busybox-static)"
if grep -q 'Requesting program interpreter' <<<"$(readelf -lW "$busybox")"; then
  die "$busybox is dynamically linked: install Debian's busybox-static (bash toolchains/install-deps.sh)"
fi

mkdir -p "$cache" "$work"
exec 9>"$cache/.lock"  # one VM test at a time prepares the shared cache

# ---- kernel: on x86, the uncompressed vmlinux boots directly through its PVH entry (~3 s faster than
# the bzImage's decompressor under TCG); fall back to vmlinuz when the extraction finds no PVH note.
kernel=$vmlinuz
if [ "$arch" = x86_64 ]; then
  vmlinux="$cache/vmlinux-$release"
  flock 9
  if [ ! -f "$vmlinux" ] && [ ! -f "$vmlinux.none" ]; then
    # The bzImage carries an xz stream: find its magic and decompress the first stream.
    for offset in $(LC_ALL=C grep -obUaP '\xfd7zXZ\x00' "$vmlinuz" | cut -d: -f1); do
      # (xz stops after its stream, so tail's SIGPIPE is expected: judge by the result instead)
      { tail -c +$((offset + 1)) "$vmlinuz" | xz -dc --single-stream >"$vmlinux.tmp" 2>/dev/null; } || true
      if grep -q 'Xen.*(0x00000012)\|Xen.*PHYS32_ENTRY' <<<"$(readelf -nW "$vmlinux.tmp" 2>/dev/null)"; then
        mv "$vmlinux.tmp" "$vmlinux"
        break
      fi
    done
    rm -f "$vmlinux.tmp"
    [ -f "$vmlinux" ] || { echo "run-vm: no PVH vmlinux in $vmlinuz; booting the bzImage"; touch "$vmlinux.none"; }
  fi
  flock -u 9
  [ -f "$vmlinux" ] && kernel=$vmlinux
fi

# ---- modules in dependency order, from the .ko files' own depends= (readelf reads either arch)
module_file() {  # module_file <name>: the .ko for a module name ('-' and '_' are the same to the kernel)
  local name=$1 found
  if [ "$name" = vimc ]; then
    [ "$arch" = x86_64 ] || die "vimc is built for x86_64 only"
    flock 9
    found=$("$here/build-vimc.sh" "$cache" "$release") || exit 2
    flock -u 9
    echo "$found"
    return
  fi
  found=$(find "$kmods" -name "$name.ko" -o -name "${name//_/-}.ko" -o -name "${name//-/_}.ko" | head -n 1)
  [ -n "$found" ] || die "module $name.ko not in $kmods (is ${kdir##*/}'s linux-image complete? re-run tests/vm/fetch-kernels.sh)"
  echo "$found"
}
declare -A seen=()
order=()
visit() {
  local name=$1 file dep
  [ -z "${seen[$name]:-}" ] || return 0
  seen[$name]=1
  file=$(module_file "$name") || exit 2
  for dep in $(readelf -p .modinfo "$file" | sed -n 's/.*depends=//p' | tr ',' ' '); do visit "$dep"; done
  order+=("$file")
}
declare -A params=()
for spec in "${modules[@]}"; do
  name=${spec%%:*}
  [ "$spec" = "$name" ] || params[$name]=${spec#*:}
  visit "$name"
done

# ---- shared libraries of an ELF file, resolved in this arch's library directories (no ldd: the arm
# binaries cannot run here)
declare -A libs=()
interp=
add_libs() {
  local file=$1 needed dir path
  local i
  i=$(readelf -lW "$file" | sed -n 's/.*Requesting program interpreter: \(.*\)]/\1/p')
  [ -z "$i" ] || interp=$i
  for needed in $(readelf -dW "$file" | sed -n 's/.*(NEEDED).*Shared library: \[\(.*\)\]/\1/p'); do
    [ -z "${libs[$needed]:-}" ] || continue
    path=
    for dir in "${libdirs[@]}"; do
      if [ -e "$dir/$needed" ]; then path=$(readlink -f "$dir/$needed"); break; fi
    done
    [ -n "$path" ] || die "$file needs $needed, which is in none of ${libdirs[*]}"
    libs[$needed]=$path
    add_libs "$path"
  done
}

# ---- the initramfs: the cached base (busybox, /init, modules) plus this run's files, as two cpio
# archives back to back (the kernel unpacks both)
mods_key=$(printf '%s\n' "$arch" "${order[@]}" | md5sum | cut -c1-12)
base="$cache/base-$arch-$mods_key.cpio"
flock 9
if [ ! -f "$base" ] || [ "$here/guest-init.sh" -nt "$base" ]; then
  stage=$(mktemp -d "$cache/base.XXXXXX")
  mkdir -p "$stage/bin" "$stage/lib/modules/vm" "$stage/etc/vm"
  cp "$busybox" "$stage/bin/busybox"
  cp "$here/guest-init.sh" "$stage/init"
  chmod 755 "$stage/init"
  for file in "${order[@]}"; do cp "$file" "$stage/lib/modules/vm/"; done
  (cd "$stage" && find . | LC_ALL=C sort | cpio -o -H newc --quiet) >"$base.tmp"
  mv "$base.tmp" "$base"
  rm -rf "$stage"
fi
flock -u 9

stage="$work/stage"
rm -rf "$stage"
mkdir -p "$stage/opt/vantage/bin" "$stage/etc/vm" "$stage/lib/$triplet"
for file in "${order[@]}"; do
  name=$(basename "$file" .ko)
  key=${name//-/_}
  p=
  for k in "$name" "$key" "${name//_/-}"; do p=${params[$k]:-$p}; done
  echo "$(basename "$file") ${p//,/ }"
done >"$stage/etc/vm/modules"
printf '%s\n' "${nodes[@]}" >"$stage/etc/vm/expect-nodes"
printf '%s\n' "$run_cmd" >"$stage/etc/vm/run.sh"
echo "/lib/$triplet" >"$stage/etc/vm/library-path"
if [ -n "$serial2" ]; then
  if [ "$arch" = x86_64 ]; then echo ttyS1; else echo pci; fi >"$stage/etc/vm/serial2"
fi
for bin in "${bins[@]}"; do
  [ -f "$bin" ] || die "test program $bin does not exist (build it first)"
  "$strip" --strip-debug -o "$stage/opt/vantage/bin/$(basename "$bin")" "$bin"
  add_libs "$bin"
done
for file in "${data[@]}"; do
  [ -f "$file" ] || die "data file $file does not exist"
  cp "$file" "$stage/opt/vantage/"
done
if [ "$libcamera" = 1 ]; then
  # libcamera's vimc IPA module (with its signature, so it runs in process), its isolation proxy, and
  # its data, at the paths libcamera was built with.
  ipadir=/usr/lib/$triplet/libcamera
  [ -f "$ipadir/ipa_vimc.so" ] || die "no $ipadir/ipa_vimc.so: install Debian's libcamera-ipa (bash toolchains/install-deps.sh)"
  mkdir -p "$stage$ipadir" "$stage/usr/share/libcamera/ipa"
  cp "$ipadir"/ipa_vimc.so* "$ipadir"/vimc_ipa_proxy "$stage$ipadir/"
  cp -r /usr/share/libcamera/ipa/vimc "$stage/usr/share/libcamera/ipa/"
  add_libs "$ipadir/ipa_vimc.so"
  add_libs "$ipadir/vimc_ipa_proxy"
fi
for soname in "${!libs[@]}"; do cp "${libs[$soname]}" "$stage/lib/$triplet/$soname"; done
if [ -n "$interp" ]; then
  path=
  for dir in "${libdirs[@]}"; do
    if [ -e "$dir/${interp##*/}" ]; then path=$(readlink -f "$dir/${interp##*/}"); break; fi
  done
  [ -n "$path" ] || die "the dynamic loader $interp is in none of ${libdirs[*]}"
  mkdir -p "$stage${interp%/*}"
  cp "$path" "$stage$interp"
fi
(cd "$stage" && find . | LC_ALL=C sort | cpio -o -H newc --quiet) >"$work/extra.cpio"
cat "$base" "$work/extra.cpio" >"$work/initramfs.cpio"
rm -rf "$stage" "$work/extra.cpio"

# ---- boot. No network device at all (-nic none); -no-reboot turns the guest's reboot into QEMU's exit.
args=(-m 512M -nographic -no-reboot -nic none -kernel "$kernel" -initrd "$work/initramfs.cpio")
if [ "$arch" = x86_64 ]; then
  args+=(-accel tcg -cpu max)
else
  args+=(-M virt -cpu cortex-a57 -accel tcg)
fi
if [ -n "$serial2" ]; then
  # A second UART connected to a unix socket another process listens on: on x86 the PC's second 16550
  # (ttyS1); the arm virt machine has one PL011 (the console), so there a PCI 16550 (8250_pci, ttyS<n>).
  # guest-init.sh links it to /dev/ttyMAV0.
  [ -S "$serial2" ] || die "--serial2-socket $serial2 is not a listening unix socket"
  if [ "$arch" = x86_64 ]; then
    args+=(-serial mon:stdio -chardev "socket,id=serial2,path=$serial2" -serial chardev:serial2)
  else
    args+=(-chardev "socket,id=serial2,path=$serial2" -device pci-serial,chardev=serial2)
  fi
fi
append="console=$console quiet panic=-1 rdinit=/init"
log="$work/console.log"
echo "run-vm: booting $release ($arch, $(basename "$kernel")) with ${#order[@]} modules, timeout ${timeout_s}s"
start_ns=$(date +%s%N)
# In the background with wait, so a TERM from whoever runs us stops QEMU too.
timeout -k 5 "$timeout_s" "$qemu" "${args[@]}" -append "$append" </dev/null >"$log" 2>&1 &
qemu_pid=$!
trap 'kill "$qemu_pid" 2>/dev/null; exit 143' TERM INT
set +e
wait "$qemu_pid"
qemu_rc=$?
set -e
trap - TERM INT
elapsed=$(( ($(date +%s%N) - start_ns) / 1000000 ))
tr -d '\r' <"$log" >"$log.clean" && mv "$log.clean" "$log"
[ -z "$console_copy" ] || cp "$log" "$console_copy"

passes=$(grep -c '^PASS ' "$log" || true)
fails=$(grep -c '^FAIL ' "$log" || true)
exit_line=$(grep -a '^VANTAGE-VM-EXIT ' "$log" | tail -n 1 || true)
grep -a -E '^(PASS|FAIL|INFO) ' "$log" || true
why=
if [ "$qemu_rc" = 124 ] || [ "$qemu_rc" = 137 ]; then
  why="the VM did not finish within ${timeout_s}s and was killed"
elif [ -z "$exit_line" ]; then
  why="the guest never reported VANTAGE-VM-EXIT (qemu exit code $qemu_rc)"
elif [ "$exit_line" != "VANTAGE-VM-EXIT 0" ]; then
  why="the guest test exited with ${exit_line#VANTAGE-VM-EXIT }"
elif [ "$fails" -gt 0 ]; then
  why="$fails FAIL line(s)"
elif [ "$passes" -lt "$min_pass" ]; then
  why="only $passes PASS line(s), expected at least $min_pass"
fi
if [ -n "$why" ]; then
  echo "---- console log ($log)"
  cat "$log"
  echo "----"
  echo "run-vm: FAILED after ${elapsed} ms: $why"
  exit 1
fi
echo "run-vm: passed ($passes PASS) in ${elapsed} ms wall for boot and test"
