#!/usr/bin/env bash
# Aravis's own command-line tool against camsim-gige: arv-tool-0.8 reads the
# GenICam XML over GVCP, lists and reads every feature, writes some, and sees
# out-of-range writes refused (GVCP's invalid parameter). (Debian 12's Aravis 0.8.26 has no arv-test-0.8,
# Aravis's camera test suite: see docs/gige.md.)
#   tests/gige/arv_tool_check.sh CAMSIM_GIGE
# Exit 77 (ctest: skipped) without arv-tool-0.8.
set -uo pipefail
gige=$1
addr=127.0.0.1
command -v arv-tool-0.8 >/dev/null || { echo "arv_tool_check: no arv-tool-0.8 (aravis-tools-cli); skipped"; exit 77; }
tmp=$(mktemp -d)
"$gige" --pattern gradient --address $addr --serial TOOL1 --xml-out "$tmp/device.xml" >"$tmp/gige.log" 2>&1 &
pid=$!
trap 'kill $pid 2>/dev/null; wait $pid 2>/dev/null; rm -rf "$tmp"' EXIT
fail=0
check() {  # check DESCRIPTION COMMAND...
  if "${@:2}"; then echo "ok   $1"; else echo "FAIL $1"; fail=1; fi
}
tool() { arv-tool-0.8 -a $addr --register-cache=disable "$@"; }
for _ in $(seq 100); do tool control DeviceSerialNumber >/dev/null 2>&1 && break; sleep 0.05; done
# Waits until the device has checked the writes sent so far: two completed
# register syncs after now (a pipeline rebuild inside one can take a while in
# an unoptimised build), at most 10 s.
settle() {
  local start now
  start=$(tool control SimSyncCount | awk '{print $3}')
  for _ in $(seq 200); do
    now=$(tool control SimSyncCount | awk '{print $3}')
    [ "$now" -ge $((start + 2)) ] && return 0
    sleep 0.05
  done
  echo "settle: SimSyncCount stayed at $now"
}

check "connects by address; serial" test "$(tool control DeviceSerialNumber)" = "DeviceSerialNumber = TOOL1"
# The tool prints the XML it read from the device's memory with a newline after it.
tool genicam >"$tmp/read.xml"
check "genicam: the XML read over GVCP is the device's" \
  cmp -n "$(stat -c %s "$tmp/device.xml")" "$tmp/read.xml" "$tmp/device.xml"
tool features >"$tmp/features.txt"
for f in DeviceVendorName Width Height OffsetX PixelFormat AcquisitionMode AcquisitionStart ExposureTime \
         ExposureAuto Gain GainAuto BlackLevel TriggerSelector TriggerMode TriggerSource TriggerActivation \
         TriggerSoftware LineSelector LineSource PayloadSize SimFrameIndex; do
  grep -q "'$f'" "$tmp/features.txt" || { echo "features: no $f"; fail=1; }
done
check "features: $(grep -c "\[R[OW]\]" "$tmp/features.txt") features listed" test "$(grep -c "\[R[OW]\]" "$tmp/features.txt")" -gt 40
tool values >"$tmp/values.txt" 2>&1
check "values: every feature reads (no error)" sh -c "! grep -qi error '$tmp/values.txt'"
check "values: 640x480 BayerRG12" grep -q "'PixelFormat' = 'BayerRG12'" "$tmp/values.txt"
tool control Width=320 Height=240 PixelFormat=BayerRG8 ExposureTime=2000 Gain=6 >/dev/null
settle
check "control: writes read back" test "$(tool control Width Height PixelFormat ExposureTime GainRaw | tr '\n' ' ')" = \
  "Width = 320 px min:2 max:640 inc:2 Height = 240 px min:2 max:480 inc:2 PixelFormat = BayerRG8 ExposureTime = 2000 us min:1 max:1e+08 GainRaw = 60 min:0 max:480 "
check "control: PayloadSize follows (320 x 240 x 1 B)" test "$(tool control PayloadSize)" = "PayloadSize = 76800"
out=$(arv-tool-0.8 -a $addr --range-check=enable control Width=9999 2>&1)
check "range check on: the XML's maximum refuses Width=9999" sh -c "echo '$out' | grep -q 'greater than allowed maximum'"
out=$(tool control Width=9999 ExposureTime=-5 2>&1)
check "range check off: both writes fail with the device's invalid parameter" \
  test "$(echo "$out" | grep -c 'write error.*(invalid-parameter)')" -eq 2
settle
check "range check off: the device refuses Width=9999 and ExposureTime=-5" test \
  "$(tool control Width ExposureTime | tr '\n' ' ')" = "Width = 320 px min:2 max:640 inc:2 ExposureTime = 2000 us min:1 max:1e+08 "
kill -INT $pid
wait $pid
check "camsim-gige stops cleanly on SIGINT" test $? -eq 0
grep -q "register writes refused" "$tmp/gige.log" || { echo "no summary in the log"; fail=1; }
[ $fail -eq 0 ] || { cat "$tmp/gige.log"; exit 1; }
echo "arv_tool_check: all passed"
