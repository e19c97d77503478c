"""Shared fixtures: the command-line binary, and a short record simulated by it."""

import csv
import json
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def binary():
    """The `hystbench` binary built from this checkout (`HYSTBENCH_BIN` overrides)."""
    b = os.environ.get("HYSTBENCH_BIN")
    if b:
        return pathlib.Path(b)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "release" / "hystbench"


@pytest.fixture(scope="session")
def cli():
    b = binary()
    if not b.exists():
        raise RuntimeError(f"{b}: build the command line first (cargo build --release)")

    def run(*args, ok=True):
        p = subprocess.run([str(b), *map(str, args)], capture_output=True, text=True)
        if ok and p.returncode != 0:
            raise AssertionError(f"hystbench {' '.join(map(str, args))} failed: {p.stderr}")
        return p

    return run


def read_csv(path):
    """Columns by name, every cell parsed exactly (Python's float is correctly rounded)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    names = rows[0]
    return {n: [float(r[i]) for r in rows[1:]] for i, n in enumerate(names)}


def short_scenario(name, samples):
    """A shipped scenario cut to `samples` samples (the split kept as a share)."""
    spec = json.loads((REPO / "scenarios" / f"{name}.json").read_text())
    spec["samples"] = samples
    spec["split"] = {k: samples // 2 for k in spec["split"]}
    return spec


@pytest.fixture(scope="session")
def record_1dof(tmp_path_factory, cli):
    """A 4,000-sample record of the shipped Bouc-Wen piezo on the seed scenario, written by
    `hystbench simulate`: (csv path, scenario path, columns)."""
    d = tmp_path_factory.mktemp("rec1")
    scen = d / "scenario.json"
    scen.write_text(json.dumps(short_scenario("seed_1dof", 4000)))
    out = d / "bw.csv"
    cli("simulate", "--plant", REPO / "plants" / "bouc_wen_piezo.json", "--scenario", scen,
        "--out", out)
    return out, scen, read_csv(out)
