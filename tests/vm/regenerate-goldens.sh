#!/usr/bin/env bash
# Recomputes tests/vm/goldens/*.txt: boots the VM with the guest programs in --print-goldens mode and
# writes the GOLDEN lines they print. Only after a deliberate change (a new kernel whose test pattern
# changed, a changed gray conversion): review the diff before committing it.
# usage: tests/vm/regenerate-goldens.sh <build-dir>   (a host build with vm_v4l2_vivid [and vm_libcamera_vimc] built)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:?usage: regenerate-goldens.sh <build-dir>}
bins="$build/tests/vm"
work="$build/tests/vm/work/regenerate-goldens"
cache="$build/tests/vm/cache"

write_goldens() {  # write_goldens <file> <device word> <console log>
  local file=$1 device=$2 log=$3
  {
    sed -n '/^# /p' "$file"
    sed -n "s/^GOLDEN \\($device .*\\)$/\\1/p" "$log" | sort
  } >"$file.new"
  if ! grep -q "^$device " "$file.new"; then
    rm -f "$file.new"
    echo "regenerate-goldens: no GOLDEN lines for $device (see $log)" >&2
    exit 1
  fi
  mv "$file.new" "$file"
  echo "regenerate-goldens: wrote $file"
}

[ -x "$bins/vm_v4l2_vivid" ] || { echo "regenerate-goldens: build vm_v4l2_vivid in $build first" >&2; exit 1; }
bash "$here/run-vm.sh" --arch x86_64 --work "$work/vivid" --cache "$cache" \
  --modules "vivid:n_devs=1,node_types=0x1,multiplanar=1" --expect-node /dev/video0 \
  --bin "$bins/vm_v4l2_vivid" --data "$here/goldens/vivid.txt" \
  --run "vm_v4l2_vivid /dev/video0 vivid.txt --print-goldens" --console-copy "$work/vivid.log" || true
write_goldens "$here/goldens/vivid.txt" vivid "$work/vivid.log"

if [ -x "$bins/vm_libcamera_vimc" ]; then
  bash "$here/run-vm.sh" --arch x86_64 --work "$work/vimc" --cache "$cache" --modules vimc \
    --expect-node /dev/media0 --libcamera --bin "$bins/vm_libcamera_vimc" --data "$here/goldens/vimc.txt" \
    --run "vm_libcamera_vimc vimc.txt --print-goldens" --console-copy "$work/vimc.log" || true
  write_goldens "$here/goldens/vimc.txt" vimc "$work/vimc.log"
fi
