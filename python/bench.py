"""The cost of calling hystbench from Python against the command line, in one run.

    python python/bench.py [--repeats 5] [--bin target/release/hystbench]

Same work both ways, alternated, median of the repeats, and the ratio Python / command line:
- a 1,000,000-sample simulation (`simulate --scenario` writing its CSV, against
  `Plant.simulate_scenario` returning arrays);
- the default identification of a 50,000-sample record (`identify --data` reading the CSV,
  against `Narx().fit` on the arrays read from it).
Ratios, not seconds: these machines are noisy.
"""

import argparse
import csv
import json
import pathlib
import statistics
import subprocess
import tempfile
import time

import numpy as np

import hystbench as hb

REPO = pathlib.Path(__file__).resolve().parents[1]


def timed(f):
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "hystbench"))
    a = ap.parse_args()
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="hystbench-bench-"))
    plant_file = REPO / "plants" / "bouc_wen_piezo.json"

    def cli(*args):
        subprocess.run([a.bin, *map(str, args)], check=True, capture_output=True)

    # 1,000,000 samples of the seed scenario at 10 kHz
    spec = json.loads((REPO / "scenarios" / "seed_1dof.json").read_text())
    spec["samples"] = 1_000_000
    spec["split"] = {"train": 500_000, "test": 500_000}
    big = tmp / "big.json"
    big.write_text(json.dumps(spec))
    plant = hb.Plant.from_file(plant_file)
    scenario = hb.Scenario.from_file(big)

    # the 50,000-sample seed record, as a file and as arrays read from it
    rec_file = tmp / "seed.csv"
    cli("simulate", "--plant", plant_file, "--scenario", REPO / "scenarios" / "seed_1dof.json",
        "--out", rec_file)
    with open(rec_file, newline="") as f:
        rows = list(csv.reader(f))
    cols = {n: np.array([float(r[i]) for r in rows[1:]]) for i, n in enumerate(rows[0])}

    jobs = {
        "simulate 1,000,000 samples": (
            lambda: cli("simulate", "--plant", plant_file, "--scenario", big, "--out",
                        tmp / "out.csv", "--force"),
            lambda: plant.simulate_scenario(scenario),
        ),
        "identify 50,000 samples": (
            lambda: cli("identify", "--data", rec_file, "--out", tmp / "m.json", "--force"),
            lambda: hb.Narx().fit(cols["u"], cols["y"], cols["t"]),
        ),
    }
    print(f"{'job':<30} {'CLI s':>8} {'Python s':>9} {'Python / CLI':>13}")
    for name, (c, p) in jobs.items():
        tc, tp = [], []
        for _ in range(a.repeats):
            tc.append(timed(c))
            tp.append(timed(p))
        mc, mp = statistics.median(tc), statistics.median(tp)
        print(f"{name:<30} {mc:8.3f} {mp:9.3f} {mp / mc:13.3f}")


if __name__ == "__main__":
    main()
