#!/bin/sh
# `kinecal check` with one seat's rows on the real Panda socket data (docs/drift.md, "An
# instrument's rows"): the general path calibrates on six placements (docs/tutorial-instruments.md),
# then each socket of the three held-out placements (one seat, 30–33 poses) is checked against
# that calibration, as measured and with the controller's joint 2 or joint 4 reading moved by
# SHIFT degrees. Prints, per shift and joint, how many seats were "still calibrated" (exit 0) and
# "drifted" (exit 2), and of the drifted how many name that joint's offset first.
#
#   sh examples/panda_check.sh DATA_DIR [KINECAL]
#
# DATA_DIR is the mukca-panda folder (panda.urdf, panda_2/); KINECAL the binary (default: kinecal
# on the PATH). Files go to a temporary directory.
set -eu
D=$(cd "$1" && pwd)
K=${2:-kinecal}
case $K in /*) ;; */*) K=$(pwd)/$K ;; esac
W=$(mktemp -d)
cd "$W"
"$K" model import "$D/panda.urdf" --tip ball_link -o panda.toml >/dev/null
ident=""
for p in back_left back_right front_center front_left front_right high; do
    for s in 0 1; do ident="$ident --seat $D/panda_2/$p/socket_$s.csv"; done
done
# shellcheck disable=SC2086
"$K" data join panda.toml $ident --angles rad --out ident.csv >/dev/null
"$K" identify panda.toml ident.csv --out cal.toml --seat-distance 0:1:50 --seat-distance 2:3:50 \
    --seat-distance 4:5:50 --seat-distance 6:7:50 --seat-distance 8:9:50 --seat-distance 10:11:50 >/dev/null || true
for p in mid-high mid_left mid_right; do
    for s in 0 1; do "$K" data join panda.toml --seat "$D/panda_2/$p/socket_$s.csv" --angles rad --out "seat_${p}_$s.csv" >/dev/null; done
done
for case in "0 2" "0.05 2" "0.1 2" "0.2 2" "0.05 4" "0.1 4" "0.2 4"; do
    set -- $case
    shift_deg=$1
    joint=$2
    still=0
    drifted=0
    named=0
    for f in seat_*.csv; do
        # Column 1 is the id: joint j is column j + 1.
        awk -F, -v OFS=, -v s="$shift_deg" -v c=$((joint + 1)) 'NR == 1 { print; next } { $c = $c + s; print }' "$f" >moved.csv
        if "$K" check cal.toml moved.csv >out.txt 2>&1; then
            still=$((still + 1))
        else
            rc=$?
            [ $rc -eq 2 ] || { echo "kinecal check exited $rc on $f" >&2; exit 1; }
            drifted=$((drifted + 1))
            grep -q "^explained by: joint panda_joint${joint} offset\|closest: joint panda_joint${joint} offset" out.txt && named=$((named + 1))
        fi
    done
    echo "joint $joint reading moved by $shift_deg deg: 6 held-out seats: still calibrated $still, drifted $drifted (joint $joint's offset named first $named)"
done
