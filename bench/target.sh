#!/usr/bin/env bash
# Kestrel on the flight-controller target: builds the firmware (firmware/), runs it on QEMU's
# STM32F405 (netduinoplus2) and prints instructions per stage and per frame, static RAM, stack
# high-water mark and flash for 100 tracks at 160x120. The last line is machine-readable:
#   instructions_per_frame=<int> static_ram=<bytes> stack_peak=<bytes> flash=<bytes> tracks=<int>
#   sensor_instructions_per_frame=<int> sensor_flow_error_px=<px> pipeline_instructions_per_frame=<int>
#   kestrel_flash=<bytes> dense_instructions_per_frame=<int> kestrel_inlined_flash=<bytes>
# Exits non-zero when the firmware reports a wrong result, or QEMU fails or hangs.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
# Far above a normal run (a few seconds), far below CI's limit.
run_timeout=300

# shellcheck source=bench/firmware_prerequisites.sh
. "$root/bench/firmware_prerequisites.sh"

cd "$root/firmware"
cargo build --release
elf="$root/firmware/target/$target/release/firmware"

log="$(mktemp)"
trap 'rm -f "$log"' EXIT
# `cargo run` uses the QEMU runner of firmware/.cargo/config.toml, the one place that spells out
# the machine and the instruction counting.
status=0
timeout --kill-after=10 "$run_timeout" cargo run --release --quiet >"$log" || status=$?
if [ "$status" -ne 0 ]; then
    cat "$log" >&2
    if [ "$status" -eq 124 ] || [ "$status" -eq 137 ]; then
        echo "error: the firmware did not finish within ${run_timeout} s" >&2
    else
        echo "error: the firmware failed (QEMU exit status $status)" >&2
    fi
    exit 1
fi
python3 "$root/bench/target_report.py" "$elf" "$root/memory.x" "$log"
# The flow sensor's OPTICAL_FLOW_RAD frames, byte for byte: tests/flow_sensor_firmware.rs gets
# the same from the library on the host.
readouts="$root/tests/data/flow_sensor_firmware.txt"
if ! diff -u "$readouts" <(grep '^sensor_readout ' "$log" | cut -d' ' -f2) >&2; then
    echo "error: the firmware's flow-sensor readouts differ from $readouts" >&2
    exit 1
fi
