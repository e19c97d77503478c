#!/usr/bin/env bash
# Do two hystbench binaries write the same outputs, bit for bit? (a refactor's safety net)
#
#   benches/same_outputs.sh BASE_BIN NEW_BIN [WORKDIR]
#
# e.g. a baseline built in a worktree of the commit before the refactor:
#   git worktree add --detach /tmp/hb-base <commit> && (cd /tmp/hb-base && cargo build --release)
#   cargo build --release && benches/same_outputs.sh /tmp/hb-base/target/release/hystbench target/release/hystbench
#
# Runs one list of commands (simulate, fit, diagnose, improve, identify, predict, compare, plot)
# with each binary, from the repository root (so that plants/ and scenarios/ resolve). Both runs
# write into the same folder, WORKDIR/out (so that paths written into files and printed are the
# same), which is then moved to WORKDIR/base or WORKDIR/new. Then every output file and the
# stdout, stderr and exit status of every command (WORKDIR/{base,new}/_cmd/NAME.{out,err,rc}) are
# compared byte for byte after masking the wall-clock fields, and only those (found by running
# one binary twice and diffing):
#   - "seconds" (grey-box model files: fit.seconds) and "train_seconds" (NARX model files,
#     `identify --json`): JSON numbers replaced by T;
#   - `fit` text: "... in 2.72 s; scored on ..."; `identify` text: "trained in 1.15 s; ...".
# PNG files are compared unmasked. The masked copies are kept in WORKDIR/masked/{base,new}
# (diff -r them to see a difference); SAME_OUTPUTS_NO_MASK=1 turns the masking off (to check
# that it is still needed).
#
# Prints one line per compared file (`same` / `DIFFERENT`), then `N same, M different`; exits 1
# if anything differs, 2 on a usage error. Commands that are expected to fail (clear errors on a
# too-short or too-poorly-excited record) are part of the list: their stderr and status are
# compared like any output. Without WORKDIR a new folder under ${TMPDIR:-/tmp} is used.
# Time: 100-155 s per binary on 2 cores (98 commands; the longest are the two fits on the
# 204,000-sample creep_piezo record, ~10 s each); ~55 MB of outputs per binary. Not covered:
# demo, sweep, split, benchmark (they need ../shared data or print timings throughout) and the
# NARX on the long 2-DoF record (~25 s).
set -euo pipefail
export LC_ALL=C
unset HYSTBENCH_TRACE

usage() {
    echo "usage: $0 BASE_BIN NEW_BIN [WORKDIR]" >&2
    exit 2
}
[ $# -ge 2 ] && [ $# -le 3 ] || usage

abs_bin() {
    if [ ! -f "$1" ] || [ ! -x "$1" ]; then
        echo "$1: not an executable file" >&2
        exit 2
    fi
    echo "$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
}
BASE_BIN=$(abs_bin "$1")
NEW_BIN=$(abs_bin "$2")
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

if [ $# -eq 3 ]; then
    mkdir -p "$3"
    WORKDIR=$(cd "$3" && pwd)
    # only ever clear a folder this script made
    if [ -n "$(ls -A "$WORKDIR")" ] && [ ! -e "$WORKDIR/.same_outputs" ]; then
        echo "$WORKDIR: not empty and not made by $0; give an empty or new folder" >&2
        exit 2
    fi
    rm -rf "$WORKDIR/out" "$WORKDIR/base" "$WORKDIR/new" "$WORKDIR/masked"
else
    WORKDIR=$(mktemp -d "${TMPDIR:-/tmp}/same_outputs.XXXXXX")
fi
touch "$WORKDIR/.same_outputs"
cd "$ROOT"

BIN=
O="$WORKDIR/out"

# run NAME ARGS...: `$BIN ARGS`, its stdout, stderr and exit status into $O/_cmd/NAME.{out,err,rc}
run() {
    local name=$1
    shift
    if [ -e "$O/_cmd/$name.rc" ]; then
        echo "$0: command name $name used twice" >&2
        exit 2
    fi
    local rc=0
    "$BIN" "$@" > "$O/_cmd/$name.out" 2> "$O/_cmd/$name.err" || rc=$?
    echo "$rc" > "$O/_cmd/$name.rc"
    printf '%s\t%s\n' "$name" "$*" >> "$O/_cmd/commands.tsv"
}

# The plant's default scenario (its "default_scenario", relative to the plant file), as a path
# from the repository root.
default_scenario() {
    local rel
    rel=$(sed -nE 's/^ *"default_scenario": *"([^"]+)".*/\1/p' "$1" | head -n 1)
    if [ -z "$rel" ]; then
        echo "$1: no default_scenario" >&2
        exit 2
    fi
    realpath -m --relative-to="$ROOT" "$(dirname "$1")/$rel"
}

# The longer 2-DoF record (docs/narx.md): seed_2dof's 500 samples are too few for a coupling fit
# (it needs ~950; the refusal is one of the commands below).
write_long_2dof_scenario() {
    cat > "$1" <<'EOF'
{
  "name": "long_2dof",
  "description": "piezo_2dof at 5 kHz: 6,000 samples, 40 V sines at 20 Hz (u1) and 7 Hz (u2), halves; 0.01 um noise.",
  "sampling_period_s": 0.0002,
  "samples": 6000,
  "split": {
    "train": 3000,
    "test": 3000
  },
  "noise_std": 0.01,
  "seed": 2,
  "inputs": [
    {
      "sine": {
        "amplitude": 40.0,
        "frequency_hz": 20.0
      }
    },
    {
      "sine": {
        "amplitude": 40.0,
        "frequency_hz": 7.0
      }
    }
  ]
}
EOF
}

# diag NAME DATA MODEL: diagnose, as text and --json
diag() {
    run "diagnose_$1" diagnose --data "$2" --model "$3"
    run "diagnose_$1_json" diagnose --data "$2" --model "$3" --json
}

# The command list. Everything it writes is under $O; names: effects with `+` for `,`.
commands() {
    local R=$O/rec F=$O/fit N=$O/narx P=$O/pred C=$O/compare I=$O/improve G=$O/fig S=$O/scenarios
    mkdir -p "$O/_cmd" "$R" "$F" "$N" "$P" "$C" "$I" "$G" "$S"

    # --- simulate: every shipped plant on its default scenario, and with --seed 1
    local plant n sc
    for plant in plants/*.json; do
        n=$(basename "$plant" .json)
        sc=$(default_scenario "$plant")
        run "simulate_$n" simulate --plant "$plant" --scenario "$sc" --out "$R/$n.csv"
        run "simulate_${n}_seed1" simulate --plant "$plant" --scenario "$sc" --seed 1 --out "$R/${n}_seed1.csv"
    done
    write_long_2dof_scenario "$S/long_2dof.json"
    run simulate_piezo_2dof_long simulate --plant plants/piezo_2dof.json --scenario "$S/long_2dof.json" --out "$R/piezo_2dof_long.csv"
    # recorded inputs instead of a scenario
    run simulate_hidden_creep_piezo_input simulate --plant plants/hidden_creep_piezo.json --input "$R/bouc_wen_piezo.csv" --noise 0.01 --seed 5 --out "$R/hidden_creep_piezo_input.csv"
    # refused: the 800 Hz mode is above the 500 Hz Nyquist frequency of the 1 kHz record
    run simulate_nyquist_refused simulate --plant plants/bouc_wen_piezo.json --input "$R/hidden_creep_piezo.csv" --out "$R/bouc_wen_piezo_input.csv"
    run simulate_piezo_2dof_input_swapped simulate --plant plants/piezo_2dof.json --input "$R/piezo_2dof_long.csv" --input-columns u2,u1 --out "$R/piezo_2dof_input_swapped.csv"

    local BW=$R/bouc_wen_piezo.csv PI=$R/prandtl_ishlinskii_piezo.csv HC=$R/hidden_creep_piezo.csv
    local CP=$R/creep_piezo.csv BB=$R/bouc_wen_benchmark.csv AS=$R/prandtl_ishlinskii_asymmetric.csv
    local D2=$R/piezo_2dof.csv L2=$R/piezo_2dof_long.csv

    # --- fit (--json unless named _text)
    local e
    for e in hysteresis,dynamics hysteresis,creep,dynamics bouc-wen,dynamics prandtl-ishlinskii none hysteresis,viscous; do
        run "fit_bw_${e//,/+}" fit --data "$BW" --effects "$e" --out "$F/bw_${e//,/+}.json" --json
        run "fit_hc_${e//,/+}" fit --data "$HC" --effects "$e" --out "$F/hc_${e//,/+}.json" --json
    done
    run fit_bw_hysteresis+dynamics_text fit --data "$BW" --effects hysteresis,dynamics --out "$F/bw_hysteresis+dynamics_text.json"
    run fit_bw_hysteresis+viscous_text fit --data "$BW" --effects hysteresis,viscous --out "$F/bw_hysteresis+viscous_text.json"
    run fit_bw_seed1_train_fraction fit --data "$R/bouc_wen_piezo_seed1.csv" --effects hysteresis,dynamics --train-fraction 0.5 --out "$F/bw_seed1_hysteresis+dynamics_tf05.json" --json
    run fit_hc_train_fraction_plays_text fit --data "$HC" --effects hysteresis,creep,dynamics --train-fraction 0.6 --plays 20 --out "$F/hc_hysteresis+creep+dynamics_tf06_p20.json"
    for e in hysteresis,dynamics prandtl-ishlinskii bouc-wen,dynamics; do
        run "fit_pi_${e//,/+}" fit --data "$PI" --effects "$e" --out "$F/pi_${e//,/+}.json" --json
    done
    run fit_as_hysteresis+dynamics_text fit --data "$AS" --effects hysteresis,dynamics --out "$F/as_hysteresis+dynamics.json"
    # 204,000 samples: ~10 s each
    run fit_cp_hysteresis+dynamics fit --data "$CP" --effects hysteresis,dynamics --out "$F/cp_hysteresis+dynamics.json" --json
    run fit_cp_hysteresis+creep+dynamics fit --data "$CP" --effects hysteresis,creep,dynamics --out "$F/cp_hysteresis+creep+dynamics.json" --json
    run fit_bb_hysteresis+dynamics fit --data "$BB" --effects hysteresis,dynamics --out "$F/bb_hysteresis+dynamics.json" --json
    run fit_bb_creep_refused fit --data "$BB" --effects hysteresis,creep,dynamics --out "$F/bb_hysteresis+creep+dynamics.json" --json
    run fit_2dof_bouc-wen+dynamics fit --data "$D2" --effects bouc-wen,dynamics --out "$F/2dof_bouc-wen+dynamics.json" --json
    run fit_2dof_none fit --data "$D2" --effects none --out "$F/2dof_none.json" --json
    run fit_2dof_too_short fit --data "$D2" --effects hysteresis,dynamics --out "$F/2dof_hysteresis+dynamics.json" --json
    for e in hysteresis,coupling,dynamics hysteresis,dynamics bouc-wen,dynamics; do
        run "fit_2dof_long_${e//,/+}" fit --data "$L2" --effects "$e" --out "$F/2dof_long_${e//,/+}.json" --json
    done
    run fit_2dof_long_coupling_text fit --data "$L2" --effects hysteresis,coupling,dynamics --out "$F/2dof_long_hysteresis+coupling+dynamics_text.json"

    # --- identify (NARX): --json unless named _text
    run identify_bw_default identify --data "$BW" --out "$N/bw_default.json" --json
    run identify_2dof_default identify --data "$D2" --out "$N/2dof_default.json" --json
    run identify_bw_hysteresis identify --data "$BW" --features hysteresis --out "$N/bw_hysteresis.json" --json
    run identify_bw_creep identify --data "$BW" --features creep --out "$N/bw_creep.json" --json
    run identify_bw_dynamics+viscous identify --data "$BW" --features dynamics,viscous --out "$N/bw_dynamics+viscous.json" --json
    run identify_bw_none identify --data "$BW" --features none --out "$N/bw_none.json" --json
    run identify_hc_creep identify --data "$HC" --features creep --out "$N/hc_creep.json" --json
    run identify_2dof_coupling identify --data "$D2" --features coupling --out "$N/2dof_coupling.json" --json
    run identify_pi_default_text identify --data "$PI" --out "$N/pi_default.json"
    run identify_2dof_study_text identify --data "$D2" --protocol study --epochs 50 --out "$N/2dof_study.json"

    # --- predict
    run predict_bw_free_run predict --model "$N/bw_default.json" --data "$R/bouc_wen_piezo_seed1.csv" --out "$P/bw_default_seed1_fr.csv"
    run predict_bw_one_step predict --model "$N/bw_default.json" --data "$R/bouc_wen_piezo_seed1.csv" --mode one-step --out "$P/bw_default_seed1_osa.csv"
    run predict_bw_hysteresis predict --model "$N/bw_hysteresis.json" --data "$BW" --out "$P/bw_hysteresis_fr.csv"
    run predict_2dof predict --model "$N/2dof_default.json" --data "$R/piezo_2dof_seed1.csv" --out "$P/2dof_default_seed1_fr.csv"

    # --- diagnose (text and --json)
    diag hc_hysteresis+dynamics "$HC" "$F/hc_hysteresis+dynamics.json"
    diag hc_none "$HC" "$F/hc_none.json"
    diag bw_hysteresis+dynamics "$BW" "$F/bw_hysteresis+dynamics.json"
    diag bw_prandtl-ishlinskii "$BW" "$F/bw_prandtl-ishlinskii.json"
    diag bw_hysteresis+viscous "$BW" "$F/bw_hysteresis+viscous.json"
    diag cp_hysteresis+dynamics "$CP" "$F/cp_hysteresis+dynamics.json"
    diag bb_hysteresis+dynamics "$BB" "$F/bb_hysteresis+dynamics.json"
    diag 2dof_long_hysteresis+dynamics "$L2" "$F/2dof_long_hysteresis+dynamics.json"
    diag 2dof_bouc-wen+dynamics "$D2" "$F/2dof_bouc-wen+dynamics.json"
    diag narx_bw_default "$BW" "$N/bw_default.json"
    diag plant_bouc_wen_piezo_seed1 "$R/bouc_wen_piezo_seed1.csv" "plants/bouc_wen_piezo.json"

    # --- improve (writes a folder)
    run improve_hc_from_none improve --data "$HC" --model "$F/hc_none.json" --out "$I/hc_from_none"
    run improve_2dof_long_json improve --data "$L2" --model "$F/2dof_long_bouc-wen+dynamics.json" --train-fraction 0.5 --json --out "$I/2dof_long"
    run improve_bw_pi_quiet improve --data "$BW" --model "$F/bw_prandtl-ishlinskii.json" --max-steps 1 --quiet --out "$I/bw_pi"

    # --- compare (text, --json, --report)
    run compare_bw_seed1_text compare --data "$R/bouc_wen_piezo_seed1.csv" --model "$F/bw_hysteresis+dynamics.json"
    run compare_bw_seed1_json compare --data "$R/bouc_wen_piezo_seed1.csv" --model "$F/bw_hysteresis+dynamics.json" --json
    run compare_hc_report compare --data "$HC" --model "$F/hc_hysteresis+dynamics.json" --report "$C/hc_hysteresis+dynamics"
    run compare_2dof_long_report compare --data "$L2" --model "$F/2dof_long_hysteresis+coupling+dynamics.json" --report "$C/2dof_long_coupling"
    run compare_narx_bw compare --data "$BW" --model "$N/bw_default.json"
    run compare_plant_hc_json compare --data "$HC" --model plants/hidden_creep_piezo.json --json

    # --- a few figures
    run plot_loop_bw_svg plot loop --data "$BW" --out "$G/loop_bw.svg"
    run plot_loop_2dof_png plot loop --data "$D2" --out "$G/loop_2dof.png"
    run plot_time_pred_png plot time --data "$P/bw_default_seed1_fr.csv" --out "$G/time_bw_pred.png"
    run plot_ladder_svg plot ladder --data "$I/hc_from_none/ladder.csv" --out "$G/ladder_hc.svg"
}

# run_all LABEL BINARY: the command list with BINARY into $O, then moved to WORKDIR/LABEL
run_all() {
    local label=$1
    BIN=$2
    rm -rf "$O"
    mkdir -p "$O"
    local t0=$SECONDS
    echo "running the commands with $label: $BIN ..."
    commands
    local failed
    failed=$( (grep -L '^0$' "$O"/_cmd/*.rc || true) | wc -l)
    echo "  $((SECONDS - t0)) s, $(wc -l < "$O/_cmd/commands.tsv") commands ($failed with a non-zero exit status)"
    mv "$O" "$WORKDIR/$label"
}

run_all base "$BASE_BIN"
run_all new "$NEW_BIN"

# mask SRC DST: the wall-clock fields of SRC replaced, into DST (PNG copied as it is)
mask() {
    mkdir -p "$(dirname "$2")"
    case "$1" in
    *.png) cp "$1" "$2" ;;
    *)
        if [ -n "${SAME_OUTPUTS_NO_MASK:-}" ]; then
            cp "$1" "$2"
        else
            sed -E \
                -e 's/"(seconds|train_seconds)": *-?[0-9][0-9.eE+-]*/"\1": T/g' \
                -e 's/^(fitted .*) in [0-9]+\.[0-9]+ s; scored on /\1 in T s; scored on /' \
                -e 's/^trained in [0-9]+\.[0-9]+ s; /trained in T s; /' \
                "$1" > "$2"
        fi
        ;;
    esac
}

echo "comparing (masked copies in $WORKDIR/masked):"
same=0
different=0
while read -r f; do
    b="$WORKDIR/base/$f"
    n="$WORKDIR/new/$f"
    if [ ! -e "$b" ]; then
        echo "DIFFERENT $f (only in new)"
        different=$((different + 1))
        continue
    fi
    if [ ! -e "$n" ]; then
        echo "DIFFERENT $f (only in base)"
        different=$((different + 1))
        continue
    fi
    mask "$b" "$WORKDIR/masked/base/$f"
    mask "$n" "$WORKDIR/masked/new/$f"
    if cmp -s "$WORKDIR/masked/base/$f" "$WORKDIR/masked/new/$f"; then
        echo "same      $f"
        same=$((same + 1))
    else
        where=$(cmp "$WORKDIR/masked/base/$f" "$WORKDIR/masked/new/$f" 2>&1 | head -n 1 | sed -E 's/.*differ: //') || true
        echo "DIFFERENT $f ($where)"
        different=$((different + 1))
    fi
done < <( (cd "$WORKDIR/base" && find . -type f; cd "$WORKDIR/new" && find . -type f) | sed 's|^\./||' | sort -u)

echo "$same same, $different different"
[ "$different" -eq 0 ] || exit 1
