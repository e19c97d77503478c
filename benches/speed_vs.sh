#!/usr/bin/env bash
# Wall-clock speed of two hystbench binaries on the same commands, run alternately (A B A B ...)
# so that the machine's load falls on both alike; prints the median time of each and the ratio
# new / base per command. Usage: benches/speed_vs.sh BASE_BIN NEW_BIN [REPEATS] [WORKDIR]
# Run from the repository root (it reads plants/ and scenarios/).
set -euo pipefail
base=$1
new=$2
reps=${3:-5}
work=${4:-$(mktemp -d)}
mkdir -p "$work"
echo "work dir: $work, $reps runs each"

# records, made once with the base binary
"$base" simulate --plant plants/hidden_creep_piezo.json --scenario scenarios/hidden_effect_1khz.json \
  --out "$work/hc.csv" --force >/dev/null
"$base" simulate --plant plants/bouc_wen_piezo.json --scenario scenarios/seed_1dof.json \
  --out "$work/bw.csv" --force >/dev/null
"$base" fit --data "$work/hc.csv" --effects hysteresis,dynamics --out "$work/hd.json" --force >/dev/null

commands=(
  "simulate --plant plants/creep_piezo.json --scenario scenarios/creep_steps.json --out $work/OUT.csv --force"
  "fit --data $work/hc.csv --effects hysteresis,creep,dynamics --out $work/OUT.json --force"
  "fit --data $work/bw.csv --effects bouc-wen,dynamics --out $work/OUT.json --force"
  "diagnose --data $work/hc.csv --model $work/hd.json --json"
  "identify --data $work/bw.csv --out $work/OUT.json --force --json"
)

median() { sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }

printf '%-60s %10s %10s %8s\n' command base_s new_s ratio
for c in "${commands[@]}"; do
  : >"$work/t_base"
  : >"$work/t_new"
  for _ in $(seq "$reps"); do
    for which in base new; do
      bin=$base
      [ "$which" = new ] && bin=$new
      cmd=${c//OUT/out_$which}
      t0=$(date +%s.%N)
      # shellcheck disable=SC2086
      "$bin" $cmd >/dev/null 2>&1
      t1=$(date +%s.%N)
      echo "$t1 - $t0" | bc -l >>"$work/t_$which"
    done
  done
  mb=$(median <"$work/t_base")
  mn=$(median <"$work/t_new")
  printf '%-60s %10.3f %10.3f %8.3f\n' "${c:0:60}" "$mb" "$mn" "$(echo "$mn / $mb" | bc -l)"
done
