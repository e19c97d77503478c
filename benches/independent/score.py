#!/usr/bin/env python3
"""Score the default identifier on records of make.py (first half trains, second tests).

    python3 benches/independent/score.py DIR [--bin target/release/hystbench] [--json OUT]
        [--only 3,17,...]

Per record: `hystbench identify --data R --json` (the default, as a user runs it), its
free-run test R^2 per output; a linear ARX baseline (4 lags, least squares on the one-step
error, run free over the test half from the training half's last samples); and the ceiling
that the noise sets (the noiseless output scored against the measurement). Prints per class
the records whose every output reaches 0.99 (0.999 for 1dof-long), the same for the ARX and
the ceiling, the outputs worse than the ARX, the divergences, the time, and the 95 % band's
coverage of the test half and its width (`identify --json`'s `band_coverage_test`,
`band_width_test`).
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
        t0 = time.time()
        out = subprocess.run(
            [a.bin, "identify", "--data", os.path.join(a.dir, "records", name + ".csv"),
             "--out", os.path.join(tmp, "m.json"), "--force", "--json", "--quiet"],
            capture_output=True, text=True)
        secs = time.time() - t0
        if out.returncode != 0:
            print(f"{name}: identify failed: {out.stderr.strip()[:300]}", file=sys.stderr)
            res = {o: None for o in ys}
            bands = {o: (None, None) for o in ys}
            models = {}
        else:
            v = json.loads(out.stdout)
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
    for cls in ["1dof-long", "1dof-short", "2dof-short"]:
        rs = [r for r in results if r["class"] == cls]
        if not rs:
            continue
        floor = 0.999 if cls == "1dof-long" else 0.99

        def at(r, key):
            return all((o[key] if o[key] is not None else -1e9) >= floor for o in r["outputs"])

        worse = sum(1 for r in rs for o in r["outputs"]
                    if o["arx_r2"] is not None and (o["r2"] is None or o["r2"] < o["arx_r2"]))
        div = sum(1 for r in rs for o in r["outputs"] if o["r2"] is None)
        print(f"| {cls} (floor {floor}) | {len(rs)} | {sum(at(r, 'r2') for r in rs)} | "
              f"{sum(at(r, 'arx_r2') for r in rs)} | {sum(at(r, 'truth_r2') for r in rs)} | "
              f"{worse} | {div} | {np.mean([r['seconds'] for r in rs]):.1f} | "
              + band_cells(rs))


if __name__ == "__main__":
    main()
