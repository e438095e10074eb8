#!/usr/bin/env bash
# Kestrel's autopilot link on the emulated flight controller: builds the firmware (firmware/),
# runs it on QEMU's STM32F405 with USART2 connected to a TCP port on the host, and checks every
# MAVLink message of the live stream with pymavlink (bench/mavlink_link.py: CRC, sequence,
# heartbeat rate, values against the scene's known motion). With `--example NAME` it does the
# same for firmware/examples/NAME.rs (the flow-sensor template: `--example flow_sensor`, whose
# check also wants its cut-short frame read out at quality 0). The last line is machine-readable:
#   heartbeat=<int> optical_flow_rad=<int> optical_flow=<int> crc_errors=<int> gaps=<int>
# Exits non-zero when any check fails, or QEMU fails or hangs.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
# Far above a normal run (a few seconds with the build done), far below CI's limit.
run_timeout=180

# shellcheck source=bench/firmware_prerequisites.sh
. "$root/bench/firmware_prerequisites.sh"
if ! python3 -c "import pymavlink" 2>/dev/null; then
    echo "error: pymavlink is required (pip install pymavlink)" >&2
    exit 2
fi

# The firmware, or with `--example NAME` that example.
build=(cargo build --release --quiet)
if [ "$#" -eq 2 ] && [ "$1" = "--example" ]; then
    build+=(--example "$2")
elif [ "$#" -ne 0 ]; then
    echo "usage: bench/mavlink_link.sh [--example NAME]" >&2
    exit 2
fi
(cd "$root/firmware" && "${build[@]}")
timeout --kill-after=10 "$run_timeout" python3 "$root/bench/mavlink_link.py" "$@"
