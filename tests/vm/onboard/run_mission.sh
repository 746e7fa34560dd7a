# Guest side of the onboard VM test (busybox sh): runs vantage-onboard on the given configuration and
# turns its outcome into PASS/FAIL lines for run-vm.sh.
# usage: sh run_mission.sh <config.yaml> <expected images> <start of the expected "camera:" line>
config=$1
images=$2
camera=$3
vantage-onboard "$config" >/tmp/onboard.out 2>&1
rc=$?
cat /tmp/onboard.out
if [ "$rc" != 0 ]; then
  echo "FAIL onboard_mission: vantage-onboard exited with $rc: $(tail -n 1 /tmp/onboard.out)"
  exit 1
fi
grep -q "^camera: $camera" /tmp/onboard.out || { echo "FAIL onboard_camera: no 'camera: $camera' line"; exit 1; }
echo "PASS onboard_camera: $(grep '^camera:' /tmp/onboard.out)"
grep -q '^vehicle: link up on serial:' /tmp/onboard.out || { echo "FAIL onboard_link: no link on the serial line"; exit 1; }
echo "PASS onboard_link: $(grep '^vehicle:' /tmp/onboard.out)"
done_line=$(grep '^mission done' /tmp/onboard.out)
[ -n "$done_line" ] || { echo "FAIL onboard_mission: no 'mission done' line"; exit 1; }
captured=$(grep -c '^image ' /tmp/onboard.out)
if [ "$captured" -lt $((images - 2)) ]; then
  echo "FAIL onboard_mission: $captured next-best-view images, expected $((images - 2)) after the two initial views"
  exit 1
fi
echo "PASS onboard_mission: $done_line"
crc=$(sed -n 's/^link: .* \([0-9]*\) CRC errors.*/\1/p' /tmp/onboard.out)
if [ "$crc" != 0 ]; then
  echo "FAIL onboard_link_clean: '${crc:-no link line}' CRC errors on the serial line"
  exit 1
fi
echo "PASS onboard_link_clean: $(grep '^link:' /tmp/onboard.out)"
