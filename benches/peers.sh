#!/usr/bin/env bash
# Side-by-side speed and accuracy of hystbench and the source study's Keras identifier
# (/work/shared/peers/keras_narx.py) on the same CSV, same settings, same run.
#
#   benches/peers.sh [CSV] [KERAS_BATCH1_EPOCHS]
#
# Without CSV it writes the seed_1dof Bouc-Wen piezo record (50,000 samples). Needs
# /tmp/peers/bin/python (see /work/shared/peers/README.md); without it, it says so and exits 0.
# Settings: 4 lags, 10 neurons, RMSProp lr 0.01; batch 128 for 100 epochs, batch 1 for
# KERAS_BATCH1_EPOCHS epochs in Keras (default 1; ~40 s each) and 100 in hystbench.
set -euo pipefail
PY=/tmp/peers/bin/python
PEERS=${PEERS_DIR:-/work/shared/peers}
if [ ! -x "$PY" ]; then
    echo "no $PY: set it up per $PEERS/README.md to compare with Keras"; exit 0
fi
cd "$(dirname "$0")/.."
cargo build --release --quiet --example narx_records
cargo build --release --quiet
BIN=target/release/hystbench
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
CSV=${1:-}
if [ -z "$CSV" ]; then
    target/release/examples/narx_records "$TMP" 1 > /dev/null
    CSV=$TMP/bouc_wen_1dof.csv
fi
E1=${2:-1}
common=(--lags 4 --neurons 10 --lr 0.01)
echo "record: $CSV"
echo "Keras, batch 128, 100 epochs..."
$PY "$PEERS/keras_narx.py" "$CSV" "${common[@]}" --batch 128 --epochs 100 > "$TMP/k128.json"
echo "hystbench --protocol study, batch 128, 100 epochs..."
$BIN identify --data "$CSV" "${common[@]}" --batch 128 --epochs 100 --protocol study --out "$TMP/s128.json" --json > "$TMP/h128.json"
echo "Keras, batch 1, $E1 epoch(s)..."
$PY "$PEERS/keras_narx.py" "$CSV" "${common[@]}" --batch 1 --epochs "$E1" > "$TMP/k1.json"
echo "hystbench --protocol study, batch 1, 100 epochs..."
$BIN identify --data "$CSV" "${common[@]}" --batch 1 --epochs 100 --protocol study --out "$TMP/s1.json" --json > "$TMP/h1.json"
echo "hystbench default identify..."
$BIN identify --data "$CSV" --out "$TMP/d.json" --json > "$TMP/hd.json"
python3 - "$TMP" "$E1" <<'PYEOF'
import json, sys
d, e1 = sys.argv[1], int(sys.argv[2])
L = lambda f: json.load(open(f"{d}/{f}"))
k128, k1, h128, h1, hd = L("k128.json"), L("k1.json"), L("h128.json"), L("h1.json"), L("hd.json")
y = lambda h: next(iter(h["outputs"].values()))
f = lambda v: "diverged" if v is None else f"{v:.4f}"
print()
print("| | seconds per epoch | ratio Keras/hystbench | R2 OSA test | R2 FR test |")
print("|---|---:|---:|---:|---:|")
kb128, hb128 = k128["train_s"] / 100, h128["train_seconds"] / 100
kb1, hb1 = k1["train_s"] / e1, h1["train_seconds"] / 100
print(f"| Keras batch 128 | {kb128:.4f} | | {f(k128['r2_osa_test'])} | {f(k128['r2_fr_test'])} |")
print(f"| hystbench study batch 128 | {hb128:.5f} | {kb128 / hb128:.0f}x | {f(y(h128)['r2_osa_test'])} | {f(y(h128)['r2_fr_test'])} |")
print(f"| Keras batch 1 ({e1} epoch) | {kb1:.3f} | | | |")
print(f"| hystbench study batch 1 | {hb1:.5f} | {kb1 / hb1:.0f}x | {f(y(h1)['r2_osa_test'])} | {f(y(h1)['r2_fr_test'])} |")
print(f"| hystbench default identify (whole training {hd['train_seconds']:.2f} s) | | | {f(y(hd)['r2_osa_test'])} | {f(y(hd)['r2_fr_test'])} |")
PYEOF
