#!/bin/sh
# kinecal beside pybotics and FIGAROH on the IRB 120 real data, in one run: the same split
# (identify idx < 500, validate idx >= 500) and measurement (reflector 1, positions).
# The peers go into throwaway virtual environments (two: pybotics pins numpy < 2, FIGAROH's
# Pinocchio needs numpy >= 2); they are never dependencies of kinecal.
#
#   sh benches/peers/run.sh [DATA_DIR]        (default ../shared/data/irb120)
set -e
D=${1:-../shared/data/irb120}
V=${PEERS_VENVS:-/tmp/kinecal-peers}
cargo build --release --quiet
[ -x "$V-pybotics/bin/python" ] || { python3 -m venv "$V-pybotics" && "$V-pybotics/bin/pip" install -q pybotics; }
[ -x "$V-figaroh/bin/python" ] || { python3 -m venv "$V-figaroh" && "$V-figaroh/bin/pip" install -q figaroh; }
echo "== pybotics"
"$V-pybotics/bin/python" benches/peers/pybotics_irb120.py "$D"
echo "== FIGAROH (and kinecal on the same split)"
"$V-figaroh/bin/python" benches/peers/figaroh_irb120.py "$D" target/release/kinecal 2>/dev/null | grep -E "^(FIGAROH|  time|  pos_rmse_calibrated_mm|  pos_max_calibrated_mm|kinecal)"
