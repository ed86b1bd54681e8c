#!/bin/sh
# `kinecal check` on the real IRB 120 tracker data (docs/drift.md, "On a real machine"): the
# general path calibrates on poses idx < 500 (docs/irb120.md), then every group of N held-out
# poses (idx ≥ 500, consecutive) is checked against that calibration, as measured and with the
# controller's q2 reading moved by SHIFT degrees (a joint offset drift). Prints, per shift, how
# many groups were "still calibrated" (exit 0) and "drifted" (exit 2), and of the drifted how
# many a single pattern explains (the joint q2 offset, or another); then how many updates
# (`identify --prior`) from groups of 10 held-out poses as measured passed and failed.
#
#   sh examples/irb120_check.sh DATA_DIR [KINECAL] [N]
#
# DATA_DIR is the irb120 folder (joints_deg.csv, smr1..3.csv, base1..3.csv); KINECAL the binary
# (default: kinecal on the PATH); N poses per group (default 5). Files go to a temporary directory.
set -eu
D=$(cd "$1" && pwd)
K=${2:-kinecal}
N=${3:-5}
case $K in /*) ;; */*) K=$(pwd)/$K ;; esac
W=$(mktemp -d)
cd "$W"
"$K" model export irb120 --out irb120.toml >/dev/null
"$K" data join irb120.toml --joints "$D/joints_deg.csv" --angles deg \
    --reflector "$D/smr1.csv" --reflector "$D/smr2.csv" --reflector "$D/smr3.csv" \
    --reference "$D/base1.csv" --reference "$D/base2.csv" --reference "$D/base3.csv" --units mm --out all.csv >/dev/null
"$K" data split irb120.toml all.csv --by below:500 --out ident.csv --rest valid.csv >/dev/null
"$K" identify irb120.toml ident.csv --noise-mm 0.05 --noise-deg 0.03 --out cal.toml >/dev/null || true
rows=$(($(wc -l <valid.csv) - 1))
for shift in 0 0.05 0.1; do
    still=0
    drifted=0
    explained=0
    by_q2=0
    g=0
    while [ $((g * N + N)) -le "$rows" ]; do
        # The header, then rows g·N+1 … g·N+N of the body, q2_deg (column 3) moved by the shift.
        awk -F, -v OFS=, -v a=$((g * N + 2)) -v b=$((g * N + N + 1)) -v s="$shift" \
            'NR == 1 { print; next } NR >= a && NR <= b { $3 = $3 + s; print }' valid.csv >group.csv
        if "$K" check cal.toml group.csv >out.txt 2>&1; then
            still=$((still + 1))
        else
            rc=$?
            [ $rc -eq 2 ] || { echo "kinecal check exited $rc on group $g" >&2; exit 1; }
            drifted=$((drifted + 1))
            grep -q '^explained by' out.txt && explained=$((explained + 1))
            grep -q '^explained by: joint q2 offset' out.txt && by_q2=$((by_q2 + 1))
        fi
        g=$((g + 1))
    done
    echo "q2 reading moved by $shift deg: $g groups of $N held-out poses: still calibrated $still, drifted $drifted (explained by a pattern $explained, by the q2 offset $by_q2)"
done
passed=0
failed=0
g=0
while [ $((g * 10 + 10)) -le "$rows" ]; do
    awk -v a=$((g * 10 + 2)) -v b=$((g * 10 + 11)) 'NR == 1 || (NR >= a && NR <= b)' valid.csv >group.csv
    if "$K" identify --prior cal.toml group.csv -o updated.toml --force >/dev/null 2>&1; then
        passed=$((passed + 1))
    else
        rc=$?
        [ $rc -eq 2 ] || { echo "kinecal identify --prior exited $rc on group $g" >&2; exit 1; }
        failed=$((failed + 1))
    fi
    g=$((g + 1))
done
echo "identify --prior from $g groups of 10 held-out poses as measured: passed $passed, failed $failed"
rm -rf "$W"
