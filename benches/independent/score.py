#!/usr/bin/env python3
"""Score the default identifier on records of make.py (first half trains, second tests).

    python3 benches/independent/score.py DIR [--bin target/release/hystbench] [--json OUT]
        [--only 3,17,...] [--noiseless-training]

Per record: `hystbench identify --data R --json` (the default, as a user runs it), its
free-run test R^2 per output; a linear ARX baseline (4 lags, least squares on the one-step
error, run free over the test half from the training half's last samples); and the ceiling
that the noise sets (the noiseless output scored against the measurement). Prints per class
the records whose every output reaches 0.99 (0.999 for 1dof-long), the same for the ARX and
the ceiling, the outputs worse than the ARX, the divergences, the time, and the 95 % band's
coverage of the test half and its width (`identify --json`'s `band_coverage_test`,
`band_width_test`).

With --noiseless-training, each record is identified again with its noiseless outputs in
place of the measured ones, and a second table tells why the records below the floor miss it,
as `hystbench zoo score --noiseless-training` does: per record the first that holds of its
outputs below the floor: the true plant misses too; fitted without noise it misses the
training half; it fits the noiseless training half (its error there at most a tenth of the
test half's) and misses the test half (the training half does not determine it); it reaches
the floor fitted without noise (the noise in the training half costs it).
"""

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def read(path):
    with open(path) as fh:
        rows = list(csv.reader(fh))
    names = rows[0]
    data = np.array(rows[1:], dtype=float)
    return {n: data[:, i] for i, n in enumerate(names)}


def r2(y, p):
    p = np.asarray(p, dtype=float)
    if not np.all(np.isfinite(p)):
        return None
    return float(1 - np.sum((y - p) ** 2) / np.sum((y - np.mean(y)) ** 2))


def arx(us, y, h, lags=4):
    """Free-run test R^2 of an ARX model fitted on samples < h."""
    n = len(y)

    def row(k, yy):
        r = [yy[k - i] for i in range(1, lags + 1)]
        for u in us:
            r += [u[k - i] for i in range(1, lags + 1)]
        return r + [1.0]

    X = np.array([row(k, y) for k in range(lags, h)])
    try:
        c, *_ = np.linalg.lstsq(X, y[lags:h], rcond=None)
    except np.linalg.LinAlgError:
        return None
    sim = np.array(y, dtype=float)
    scale = 1e6 * (np.max(np.abs(y[:h])) + 1.0)
    for k in range(h, n):
        sim[k] = np.dot(row(k, sim), c)
        if not np.isfinite(sim[k]) or abs(sim[k]) > scale:
            return None
    return r2(y[h:], sim[h:])


def identify(binary, path, tmp):
    """`hystbench identify --json` on `path` (None when it fails) and its wall-clock time."""
    t0 = time.time()
    out = subprocess.run(
        [binary, "identify", "--data", path, "--out", os.path.join(tmp, "m.json"), "--force",
         "--json", "--quiet"],
        capture_output=True, text=True)
    secs = time.time() - t0
    if out.returncode != 0:
        print(f"{path}: identify failed: {out.stderr.strip()[:300]}", file=sys.stderr)
        return None, secs
    return json.loads(out.stdout), secs


def noiseless_record(rec, truth, path):
    """Writes `rec` with its outputs replaced by the noiseless ones of `truth` to `path`."""
    names = list(rec)
    cols = [truth[n] if n.startswith("y") else rec[n] for n in names]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in zip(*cols):
            w.writerow([repr(float(v)) for v in row])


# how much closer than its test half a noiseless fit must fit its training half for "does not
# determine" (`zoo::score::DETERMINED_RATIO`)
DETERMINED_RATIO = 0.1

# (the precedence of a record's outputs, as `zoo score --noiseless-training`)
MISSES = ["true plant misses too", "misses the noiseless training half",
          "training half does not determine the test half", "reaches it fitted without noise"]


def miss(o, floor):
    """Why output `o` misses `floor` (an index into MISSES), None when it does not."""
    if o["r2"] is not None and o["r2"] >= floor:
        return None
    if o["truth_r2"] is None or o["truth_r2"] < floor:
        return 0
    train, test = o["noiseless_r2_train"], o["noiseless_r2"]
    if test is not None and test >= floor:
        return 3
    if train is not None and test is not None and 1 - train <= DETERMINED_RATIO * (1 - test):
        return 2
    return 1


def by_class(results):
    """Per class scored, in order: its name, its records and its floor."""
    for cls in ["1dof-long", "1dof-short", "2dof-short"]:
        rs = [r for r in results if r["class"] == cls]
        if rs:
            yield cls, rs, 0.999 if cls == "1dof-long" else 0.99


def band_cells(rs):
    """The class's band columns: mean coverage, outputs covered >= 90 %, median half-width
    (test output standard deviations)."""
    cov = [o["coverage"] for r in rs for o in r["outputs"] if o.get("coverage") is not None]
    wid = [o["band_width"] for r in rs for o in r["outputs"] if o.get("band_width") is not None]
    if not cov:
        return "- | - | - |"
    width = f"{np.median(wid):.3f}" if wid else "-"
    return f"{100 * np.mean(cov):.1f} % | {sum(c >= 0.9 for c in cov)} of {len(cov)} | {width} |"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--bin", default="target/release/hystbench")
    ap.add_argument("--json", default=None)
    ap.add_argument("--only", default="")
    ap.add_argument("--noiseless-training", action="store_true")
    a = ap.parse_args()
    index = json.load(open(os.path.join(a.dir, "index.json")))["members"]
    only = set(int(x) for x in a.only.split(",") if x)
    results = []
    tmp = tempfile.mkdtemp()
    for m in index:
        if only and m["index"] not in only:
            continue
        name = f"{m['index']:04d}"
        rec = read(os.path.join(a.dir, "records", name + ".csv"))
        truth = read(os.path.join(a.dir, "truth", name + ".csv"))
        ys = [c for c in rec if c.startswith("y")]
        us = [c for c in rec if c.startswith("u")]
        n = len(rec["t"])
        h = n // 2
        v, secs = identify(a.bin, os.path.join(a.dir, "records", name + ".csv"), tmp)
        if v is None:
            res = {o: None for o in ys}
            bands = {o: (None, None) for o in ys}
            models = {}
        else:
            res = {o: v["outputs"][o].get("r2_fr_test") for o in ys}
            bands = {o: (v["outputs"][o].get("band_coverage_test"),
                         v["outputs"][o].get("band_width_test")) for o in ys}
            models = {c["name"]: c["effects"] + ":" + c["model"]
                      for c in (v.get("greybox") or {}).get("outputs", [])}
        row = {"index": m["index"], "class": m["class"], "seconds": secs, "outputs": []}
        for o in ys:
            y = rec[o]
            row["outputs"].append({
                "name": o,
                "r2": res[o],
                "arx_r2": arx([rec[u] for u in us], y, h),
                "truth_r2": r2(y[h:], truth[o][h:]),
                "model": models.get(o, "network"),
                "coverage": bands[o][0],
                "band_width": bands[o][1],
            })
        if a.noiseless_training:
            clean = os.path.join(tmp, "noiseless.csv")
            noiseless_record(rec, truth, clean)
            w, _ = identify(a.bin, clean, tmp)
            for x in row["outputs"]:
                s = (w or {}).get("outputs", {}).get(x["name"], {})
                x["noiseless_r2_train"] = s.get("r2_fr_train")
                x["noiseless_r2"] = s.get("r2_fr_test")
        results.append(row)
        print(name, m["class"], " ".join(
            f"{x['name']} {x['r2'] if x['r2'] is None else round(x['r2'], 4)} "
            f"(arx {x['arx_r2'] if x['arx_r2'] is None else round(x['arx_r2'], 3)}, "
            f"truth {round(x['truth_r2'], 4)}, {x['model']})" for x in row["outputs"]),
            f"{secs:.1f} s", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(results, fh, indent=1)
    print()
    print("| class | records | at the floor | ARX at it | true plant at it | worse than ARX | "
          "diverged | mean s | mean band coverage | outputs covered >= 90 % | median half-width |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for cls, rs, floor in by_class(results):

        def at(r, key):
            return all((o[key] if o[key] is not None else -1e9) >= floor for o in r["outputs"])

        worse = sum(1 for r in rs for o in r["outputs"]
                    if o["arx_r2"] is not None and (o["r2"] is None or o["r2"] < o["arx_r2"]))
        div = sum(1 for r in rs for o in r["outputs"] if o["r2"] is None)
        print(f"| {cls} (floor {floor}) | {len(rs)} | {sum(at(r, 'r2') for r in rs)} | "
              f"{sum(at(r, 'arx_r2') for r in rs)} | {sum(at(r, 'truth_r2') for r in rs)} | "
              f"{worse} | {div} | {np.mean([r['seconds'] for r in rs]):.1f} | "
              + band_cells(rs))
    if not a.noiseless_training:
        return
    print()
    print("| class | below the floor | " + " | ".join(MISSES) + " |")
    print("|---|---|---|---|---|---|")
    for cls, rs, floor in by_class(results):
        why = [min((k for k in (miss(o, floor) for o in r["outputs"]) if k is not None),
                   default=None) for r in rs]
        below = [k for k in why if k is not None]
        print(f"| {cls} | {len(below)} | "
              + " | ".join(str(below.count(k)) for k in range(len(MISSES))) + " |")


if __name__ == "__main__":
    main()
