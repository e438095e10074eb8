#!/usr/bin/env bash
# The firmware template (firmware/examples/flow_sensor.rs) on the emulated flight controller:
# builds it, runs it on QEMU's STM32F405 with USART2 connected to a TCP port on the host, and
# checks every MAVLink message of the live stream with pymavlink, as bench/mavlink_link.sh does
# for the firmware (bench/mavlink_link.py --example flow_sensor: CRC, sequence, heartbeat rate,
# values against the scene's known motion, the bad frame at quality 0). The last line is
# machine-readable:
#   heartbeat=<int> optical_flow_rad=<int> optical_flow=<int> crc_errors=<int> gaps=<int>
# Exits non-zero when any check fails, or QEMU fails or hangs.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
# Far above a normal run (about a second with the build done), far below CI's limit.
run_timeout=180

# shellcheck source=bench/firmware_prerequisites.sh
. "$root/bench/firmware_prerequisites.sh"
if ! python3 -c "import pymavlink" 2>/dev/null; then
    echo "error: pymavlink is required (pip install pymavlink)" >&2
    exit 2
fi

(cd "$root/firmware" && cargo build --release --quiet --example flow_sensor)
timeout --kill-after=10 "$run_timeout" python3 "$root/bench/mavlink_link.py" --example flow_sensor
