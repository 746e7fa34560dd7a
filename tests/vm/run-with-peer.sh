#!/usr/bin/env bash
# Runs a VM test whose guest speaks MAVLink on its second serial port (ttyS1) to the node-mavlink
# vehicle peer (tests/mavlink_peer) on this machine: the peer binds UDP on 127.0.0.1, socat listens on a
# unix socket that QEMU's second UART connects to and relays it to the peer's port. No network device in
# the VM. After the VM, the peer's own decode of what it received is checked (--peer-expect, a regex on
# its JSON lines, may be repeated).
# usage: run-with-peer.sh --work DIR [--peer-args "..."] [--peer-expect REGEX]... -- <run-vm.sh arguments>
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
peer_dir="$here/../mavlink_peer"

die() { echo "run-with-peer: $*" >&2; exit 2; }

work= peer_args="--duration-s 120" expects=()
while [ $# -gt 0 ]; do
  case $1 in
    --work) work=$2; shift 2 ;;
    --peer-args) peer_args=$2; shift 2 ;;
    --peer-expect) expects+=("$2"); shift 2 ;;
    --) shift; break ;;
    *) die "unknown argument '$1'" ;;
  esac
done
[ -n "$work" ] || die "--work is required"
command -v node >/dev/null || die "node not found: install Node.js (bash toolchains/install-deps.sh)"
command -v socat >/dev/null || die "socat not found: install Debian's socat (bash toolchains/install-deps.sh)"
[ -d "$peer_dir/node_modules/node-mavlink" ] ||
  die "the peer's npm packages are missing: run bash tests/mavlink_peer/install.sh (or toolchains/install-deps.sh)"

mkdir -p "$work"
sock="$work/serial2.sock"
peer_log="$work/peer.log"
rm -f "$sock" "$peer_log"
peer_pid= socat_pid= vm_pid=
cleanup() {
  # Only the processes started here, by their ids (run-vm.sh stops its own QEMU on TERM).
  [ -z "$vm_pid" ] || kill "$vm_pid" 2>/dev/null || true
  [ -z "$socat_pid" ] || kill "$socat_pid" 2>/dev/null || true
  [ -z "$peer_pid" ] || kill "$peer_pid" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT
trap 'exit 143' TERM INT  # (exit runs the EXIT trap: the peer and socat go with us)

# shellcheck disable=SC2086  # peer_args are separate words on purpose
node "$peer_dir/peer.js" $peer_args </dev/null >"$peer_log" 2>&1 &
peer_pid=$!
port=
for _ in $(seq 100); do
  port=$(sed -n 's/^PORT \([0-9]*\)$/\1/p' "$peer_log" | head -n 1)
  [ -z "$port" ] || break
  kill -0 "$peer_pid" 2>/dev/null || { cat "$peer_log"; die "the peer exited before printing its port"; }
  sleep 0.1
done
[ -n "$port" ] || { cat "$peer_log"; die "the peer printed no port within 10 s"; }

# Serial bytes from the guest go out as UDP datagrams from one local port (the peer answers it); the
# peer's datagrams come back as bytes on the line.
socat -b 4096 "UNIX-LISTEN:$sock,unlink-early" "UDP4:127.0.0.1:$port" </dev/null >"$work/socat.log" 2>&1 &
socat_pid=$!
for _ in $(seq 50); do [ -S "$sock" ] && break; sleep 0.1; done
[ -S "$sock" ] || die "socat did not create $sock"
echo "run-with-peer: peer on udp 127.0.0.1:$port, the guest's second UART via $sock"

# In the background with wait, so a TERM (ctest's timeout) reaches the trap at once.
bash "$here/run-vm.sh" "$@" --serial2-socket "$sock" &
vm_pid=$!
set +e
wait "$vm_pid"
rc=$?
set -e
vm_pid=

missing=0
for regex in "${expects[@]}"; do
  if grep -Eq -- "$regex" "$peer_log"; then
    echo "PASS peer_saw: $regex"
  else
    echo "FAIL peer_saw: no line of the peer's log matches $regex"
    missing=1
  fi
done
if [ "$rc" != 0 ] || [ "$missing" != 0 ]; then
  echo "---- peer log (last 30 lines of $peer_log)"
  tail -n 30 "$peer_log"
  [ ! -s "$work/socat.log" ] || { echo "---- socat"; cat "$work/socat.log"; }
  exit 1
fi
