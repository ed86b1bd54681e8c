#!/bin/sh
# Held-out placements as validation on the real Panda socket data (docs/instruments.md, "Held-out
# placements"): one-to-many (identify on one placement, judge the eight others) and all-but-one
# (identify on eight placements, judge the one left out), each through `identify --validation`
# beside `validate` of the written model on the same file. Prints one table row per run.
#
#   sh examples/panda_held_out.sh DATA_DIR [KINECAL]
#
# DATA_DIR is the mukca-panda folder (panda.urdf, panda_2/<placement>/socket_{0,1}.csv); KINECAL
# the binary (default: kinecal on the PATH). Every file goes to a temporary directory.
set -eu
D=$(cd "$1" && pwd)
K=${2:-kinecal}
case $K in /*) ;; */*) K=$(pwd)/$K ;; esac
W=$(mktemp -d)
cd "$W"
"$K" model import "$D/panda.urdf" --tip ball_link -o panda.toml >/dev/null
places=$(ls "$D/panda_2")

# join OUT PLACEMENT…: the placements' sockets as seats 0, 1, 2, … (placement k: seats 2k, 2k+1).
join() {
    out=$1
    shift
    args=""
    for place in "$@"; do
        args="$args --seat $D/panda_2/$place/socket_0.csv --seat $D/panda_2/$place/socket_1.csv"
    done
    # shellcheck disable=SC2086
    "$K" data join panda.toml $args --angles rad --out "$out" --force >/dev/null
}

# fifty OPTION N: the option once per placement of N, its two sockets 50 mm apart.
fifty() {
    k=0
    while [ "$k" -lt "$2" ]; do
        printf ' %s %d:%d:50' "$1" $((2 * k)) $((2 * k + 1))
        k=$((k + 1))
    done
}

# run NAME IDENT IDENT_PLACEMENTS HELD HELD_PLACEMENTS: identify with --validation, validate.
run() {
    set +e
    # shellcheck disable=SC2046
    "$K" identify panda.toml "$2" $(fifty --seat-distance "$3") --validation "$4" \
        $(fifty --validation-seat-distance "$5") --out cal.toml --force >out.txt 2>err.txt
    rc=$?
    set -e
    spread=$(sed -n 's/^  [0-9]* seats* ([0-9]* rows): .* \([0-9.]*\) → \([0-9.]*\) mm RMS$/\1 → \2/p' out.txt)
    verdict=$(sed -n 's/^verdict: \([^:]*\).*/\1/p' out.txt)
    # shellcheck disable=SC2046
    check=$("$K" validate cal.toml "$4" $(fifty --seat-distance "$5") | sed -n 's/^all seats: spread \([0-9.]*\) mm RMS.*/\1/p')
    echo "| $1 | $rc | $verdict | $spread | $check |"
}

for p in $places; do join "$p.csv" "$p"; done
echo "| run | exit | verdict | held-out spread RMS, identify --validation: nominal → calibrated (mm) | validate cal.toml (mm) |"
echo "|---|---|---|---|---|"
for p in $places; do
    # shellcheck disable=SC2046
    join others.csv $(echo "$places" | grep -vx "$p")
    run "on $p, judged on the 8 others" "$p.csv" 1 others.csv 8
done
for p in $places; do
    # shellcheck disable=SC2046
    join others.csv $(echo "$places" | grep -vx "$p")
    run "$p held out" others.csv 8 "$p.csv" 1
done
rm -rf "$W"
