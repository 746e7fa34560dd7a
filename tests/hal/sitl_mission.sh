#!/usr/bin/env bash
# SITL on loopback: vantage-onboard (camera: sim, rendering at the pose the vehicle reports) flies a short
# NBV mission against the node-mavlink vehicle peer over UDP on 127.0.0.1.
# With "link-loss" the vehicle falls silent mid-mission: vantage-onboard must stop with exit code 4 and
# say that the link was lost.
# usage: sitl_mission.sh <vantage-onboard> <node> <peer-dir> <work-dir> [max-images] [link-loss]
set -euo pipefail
onboard=$1 node=$2 peer_dir=$3 work=$4 images=${5:-8} mode=${6:-mission}
silent=()
[ "$mode" = link-loss ] && silent=(--silent-after-s 5)
[ -f "$peer_dir/node_modules/node-mavlink/package.json" ] || { echo "FAIL: run tests/mavlink_peer/install.sh"; exit 1; }
mkdir -p "$work"
peer_out="$work/peer.out"
: >"$peer_out"  # exists before the peer opens it (the loop below reads it)
# The peer starts off the first view (NED x=-35 north, y=3 east, z=0) and flies at 20 units/s.
"$node" "$peer_dir/peer.js" --duration-s 100 --speed-mps 20 --start-ned -35,3,0 "${silent[@]}" </dev/null >"$peer_out" 2>&1 &
peer_pid=$!
trap 'kill "$peer_pid" 2>/dev/null || true; wait "$peer_pid" 2>/dev/null || true' EXIT
port=""
for _ in $(seq 100); do
  port=$(sed -n 's/^PORT //p' "$peer_out")
  [ -n "$port" ] && break
  sleep 0.1
done
[ -n "$port" ] || { echo "FAIL: the peer printed no port"; cat "$peer_out"; exit 1; }
cat > "$work/onboard.yaml" <<EOF
camera:
  driver: sim
mavlink:
  endpoint: udp:127.0.0.1:$port
  arrive_timeout_s: 20
  link_loss_timeout_s: 1.5
mission:
  max_images: $images
EOF
set +e
timeout 95 "$onboard" "$work/onboard.yaml" >"$work/onboard.out" 2>&1
rc=$?
set -e
cat "$work/onboard.out"
fail() { echo "FAIL: $*"; echo "--- peer (last lines)"; tail -5 "$peer_out"; exit 1; }
if [ "$mode" = link-loss ]; then
  [ "$rc" -eq 4 ] || fail "vantage-onboard exited with $rc, not 4, when the vehicle fell silent"
  grep -q '^vantage-onboard: vehicle: link lost' "$work/onboard.out" || fail "no 'vehicle: link lost' line"
  echo "PASS: SITL link loss reported (exit 4)"
  exit 0
fi
[ "$rc" -eq 0 ] || fail "vantage-onboard exited with $rc"
grep -q '^mission done' "$work/onboard.out" || fail "no 'mission done' line"
# The rendered frames reached the front end with texture in them (a black or garbled frame gives no seeds).
seeds=$(sed -n 's/.*front end: \([0-9]*\) seeds tried.*/\1/p' "$work/onboard.out")
[ "${seeds:-0}" -gt 1000 ] || fail "the initial frames gave ${seeds:-no} textured seeds"
# ... and the two-view initialization built a model from them.
initial=$(sed -n 's/^mission: started from .*: \([0-9]*\) primitives.*/\1/p' "$work/onboard.out")
[ "${initial:-0}" -gt 100 ] || fail "the initial two images gave ${initial:-no} primitives"
# ... and the tracked images matched the model's primitives (the end-of-mission tracking line).
tracked=$(sed -n 's/^tracking: \([0-9]*\) observations predicted in view.*/\1/p' "$work/onboard.out")
[ "${tracked:-0}" -gt 1000 ] || fail "the tracked images predicted ${tracked:-no} observations in view"
# ... and the EKF tested their innovations (the end-of-mission innovations line, its consistency check).
tested=$(sed -n 's/^innovations: \([0-9]*\) tested by the gate.*/\1/p' "$work/onboard.out")
[ "${tested:-0}" -gt 100 ] || fail "the EKF's gate tested ${tested:-no} innovations"
captured=$(grep -c '^image ' "$work/onboard.out" || true)
[ "$captured" -ge $((images - 2)) ] || fail "only $captured images after the initial two"
grep -q '"msg":"SET_POSITION_TARGET_LOCAL_NED"' "$peer_out" || fail "the peer saw no setpoint"
echo "PASS: SITL mission with $captured images over MAVLink on 127.0.0.1:$port"
