#!/bin/busybox sh
# /init of the test VM (busybox-static): mount the kernel's file systems, load the media modules in
# order, write the udev records libcamera needs, run the test, report, and reboot (QEMU runs with
# -no-reboot, so the reboot ends it). Output on the serial console is the protocol with run-vm.sh:
#   PASS <name> | FAIL <name>: <why>   from the test programs
#   VANTAGE-VM-EXIT <code>              last line, the test's exit code
/bin/busybox mkdir -p /bin /sbin /proc /sys /dev /run /tmp
/bin/busybox --install -s /bin
export PATH=/opt/vantage/bin:/bin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
mount -t tmpfs tmpfs /run
mount -t tmpfs tmpfs /tmp

finish() {
  echo "VANTAGE-VM-EXIT $1"
  if [ "$1" != 0 ]; then echo "--- guest dmesg (last 40 lines)"; dmesg | tail -n 40; fi
  sync
  reboot -f
  sleep 5
  poweroff -f
}

echo "VANTAGE-VM-BOOTED $(uname -r) $(uname -m)"

# Modules: one "file.ko [params...]" per line, in dependency order (no depmod needed).
while read -r module params; do
  [ -n "$module" ] || continue
  # shellcheck disable=SC2086  # params are separate words on purpose
  if ! insmod "/lib/modules/vm/$module" $params; then
    echo "FAIL vm_setup: insmod $module $params failed"
    finish 90
  fi
done < /etc/vm/modules

# Device nodes appear asynchronously after insmod; wait up to ~5 s for the ones the test names.
for node in $(cat /etc/vm/expect-nodes); do
  i=0
  while [ ! -e "$node" ] && [ $i -lt 50 ]; do sleep 0.1; i=$((i + 1)); done
  if [ ! -e "$node" ]; then
    echo "FAIL vm_setup: $node did not appear after loading the modules"
    ls -l /dev/video* /dev/media* /dev/v4l-subdev* 2>&1
    finish 91
  fi
done

# The second UART for MAVLink (run-vm.sh --serial2-socket) as /dev/ttyMAV0: ttyS1 on x86, and on arm
# the 8250 port that QEMU's PCI 16550 (vendor 0x1b36) was given.
if [ -f /etc/vm/serial2 ]; then
  tty=$(cat /etc/vm/serial2)
  if [ "$tty" = pci ]; then
    tty=
    for t in /sys/class/tty/ttyS*; do
      [ "$(cat "$t/device/vendor" 2>/dev/null)" = 0x1b36 ] && tty=${t##*/}
    done
  fi
  if [ -z "$tty" ] || [ ! -e "/dev/$tty" ]; then
    echo "FAIL vm_setup: no second UART (${tty:-no PCI serial port found})"
    finish 93
  fi
  ln -s "/dev/$tty" /dev/ttyMAV0
  echo "INFO serial2: /dev/ttyMAV0 -> /dev/$tty"
fi

# libcamera without udevd: libudev lists a device only once udev has "initialized" it, which it reads
# from /run/udev/data/c<major>:<minor> (I: is the initialization time).
mkdir -p /run/udev/data
for dev in /sys/class/video4linux/*/dev /sys/bus/media/devices/*/dev; do
  [ -r "$dev" ] || continue
  echo "I:1" > "/run/udev/data/c$(cat "$dev")"
done

cd /opt/vantage || finish 92
export LD_LIBRARY_PATH="$(cat /etc/vm/library-path)"
export LIBCAMERA_LOG_LEVELS='*:ERROR'
export HOME=/tmp
sh /etc/vm/run.sh
finish $?
