#!/usr/bin/env bash
# Time and peak memory of the commands on long records (issue "long records and big grids").
#
#   benches/scale.sh [BIN] [SAMPLES...]        (default: target/release/hystbench 200000 2000000)
#
# The record: plant `hidden_creep_piezo` on the `hidden_effect_1khz` scenario stretched to SAMPLES
# samples at 1 kHz (both halves of the scenario scaled alike: sines with random steps, then held
# levels); with SCALE_RECORD=repeated, the scenario repeated to SAMPLES samples instead (a
# multiple of 40,000: a lab's excitation run again and again, whose first tenth shows what the
# whole record shows; a fit chooses its starts on that part, docs/graybox.md). For each size, each command runs once under GNU time; the table gives the wall-clock
# seconds and the peak resident memory (MB), and the last column the ratio of the times of
# consecutive sizes against the ratio of the sizes (linear time: the two agree).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-target/release/hystbench}
shift || true
SIZES=("$@")
[ ${#SIZES[@]} -gt 0 ] || SIZES=(200000 2000000)
[ -x "$BIN" ] || { echo "$BIN: build it first (cargo build --release)" >&2; exit 2; }
W=$(mktemp -d "${TMPDIR:-/tmp}/hystbench-scale-XXXXXX")
echo "work folder: $W ($(nproc) cores)"

measure() { # name, command...: prints "name seconds MB"
    local name=$1
    shift
    /usr/bin/time -f "%e %M" -o "$W/time" "$@" >"$W/$name.out" 2>"$W/$name.err" ||
        { echo "$name failed: $(tail -1 "$W/$name.err")" >&2; return 1; }
    read -r s kb <"$W/time"
    printf '%s %s %d\n' "$name" "$s" $((kb / 1024))
}

declare -A T
printf '| command | samples | seconds | peak MB |\n|---|---|---|---|\n'
for n in "${SIZES[@]}"; do
    python3 - "$n" "${SCALE_RECORD:-stretched}" >"$W/s$n.json" <<'EOF'
import json, sys
n, how = int(sys.argv[1]), sys.argv[2]
s = json.load(open("scenarios/hidden_effect_1khz.json"))
f = n / s["samples"]
s["samples"] = n
if how == "repeated":
    if n % 40000:
        sys.exit("SCALE_RECORD=repeated: SAMPLES must be a multiple of 40000")
    s["inputs"][0]["concat"] *= n // 40000
else:
    for part in s["inputs"][0]["concat"]:
        part["duration_s"] *= f
print(json.dumps(s))
EOF
    "$BIN" simulate --plant plants/hidden_creep_piezo.json --scenario "$W/s$n.json" --out "$W/r$n.csv" 2>/dev/null
    R=$W/r$n.csv
    while read -r name; do
        case $name in
        simulate) cmd=("$BIN" simulate --plant plants/hidden_creep_piezo.json --scenario "$W/s$n.json" --out "$W/sim$n.csv" --force) ;;
        fit-hcd) cmd=("$BIN" fit --data "$R" --effects hysteresis,creep,dynamics --out "$W/hcd$n.json" --force --quiet) ;;
        fit-hd) cmd=("$BIN" fit --data "$R" --effects hysteresis,dynamics --out "$W/hd$n.json" --force --quiet) ;;
        diagnose) cmd=("$BIN" diagnose --data "$R" --model "$W/hd$n.json") ;;
        identify) cmd=("$BIN" identify --data "$R" --out "$W/narx$n.json" --force --quiet) ;;
        predict) cmd=("$BIN" predict --model "$W/narx$n.json" --data "$R" --out "$W/p$n.csv" --force) ;;
        plot-loop) cmd=("$BIN" plot loop --data "$R" --out "$W/loop$n.png" --force) ;;
        esac
        read -r _ s mb < <(measure "$name-$n" "${cmd[@]}")
        T[$name,$n]=$s
        printf '| %s | %s | %s | %s |\n' "$name" "$n" "$s" "$mb"
    done <<<"simulate
fit-hcd
fit-hd
diagnose
identify
predict
plot-loop"
done
if [ ${#SIZES[@]} -ge 2 ]; then
    a=${SIZES[0]} b=${SIZES[1]}
    echo
    echo "time ratio $b / $a samples (the sizes' ratio: $(python3 -c "print(round($b/$a, 2))")):"
    for name in simulate fit-hcd fit-hd diagnose identify predict plot-loop; do
        python3 -c "print('  $name', round(${T[$name,$b]} / max(${T[$name,$a]}, 1e-3), 2))"
    done
fi
rm -rf "$W"
