#!/usr/bin/env bash
# The zoo bench: draw a zoo and score it with the default identifier against the linear ARX
# baseline, timing both steps (the acceptance asks `zoo score` on 200 records in under 10
# minutes on 2 cores).
#
#   benches/zoo.sh [COUNT] [SEED] [WORKDIR]      # defaults: 200, 1001 (a held-out seed), a temp dir
#
# Development uses seeds 1-99; seeds from 1001 are held out for reports (docs/zoo.md).
set -euo pipefail
count=${1:-200}
seed=${2:-1001}
work=${3:-$(mktemp -d)}
bin=${HYSTBENCH:-target/release/hystbench}
[ -x "$bin" ] || cargo build --release
dir="$work/zoo_$seed"
t0=$(date +%s.%N)
"$bin" zoo --count "$count" --seed "$seed" --out "$dir" --force >/dev/null 2>&1
t1=$(date +%s.%N)
"$bin" zoo score "$dir" --quiet    # records side by side (--one-at-a-time: per-record times)
t2=$(date +%s.%N)
printf 'zoo of %s members (seed %s): made in %.1f s, scored in %.1f s (%s threads)\n' \
  "$count" "$seed" "$(echo "$t1 - $t0" | bc -l)" "$(echo "$t2 - $t1" | bc -l)" "$(nproc)"
echo "results: $dir/score/results.csv"
