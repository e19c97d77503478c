"""The Python front gives the command line's numbers on the same record, bit for bit, and
their model files are one format."""

import json

import numpy as np

import hystbench as hb
from conftest import REPO, read_csv


def same(a, b):
    """Bit for bit (NaN nowhere)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


def test_simulate_matches_cli(record_1dof):
    path, scen, cols = record_1dof
    plant = hb.Plant.from_file(REPO / "plants" / "bouc_wen_piezo.json")
    rec = plant.simulate_scenario(hb.Scenario.from_file(scen))
    assert same(rec.t, cols["t"])
    assert same(rec.u, cols["u"])
    assert same(rec.y, cols["y"])
    assert rec.provenance["samples"] == 4000


def test_simulate_input_matches_cli(tmp_path, cli, record_1dof):
    path, _, cols = record_1dof
    out = tmp_path / "again.csv"
    cli("simulate", "--plant", REPO / "plants" / "bouc_wen_piezo.json", "--input", path,
        "--noise", "0.01", "--seed", "5", "--out", out)
    y = hb.Plant.from_file(REPO / "plants" / "bouc_wen_piezo.json").simulate(
        cols["u"], np.array(cols["t"]), noise=0.01, seed=5)
    assert same(y, read_csv(out)["y"])


def test_identify_matches_cli(tmp_path, cli, record_1dof):
    path, _, cols = record_1dof
    model_file = tmp_path / "narx.json"
    p = cli("identify", "--data", path, "--epochs", "15", "--seed", "3", "--out", model_file,
            "--json")
    report = json.loads(p.stdout)
    narx = hb.Narx(epochs=15, seed=3).fit(cols["u"], cols["y"], np.array(cols["t"]))
    for r in (report, narx.scores):
        r.pop("train_seconds")
    assert narx.scores == report
    # the same network: the CLI's prediction of its own model equals Python's of its own
    pred_file = tmp_path / "pred.csv"
    cli("predict", "--model", model_file, "--data", path, "--out", pred_file)
    y_hat = narx.predict(cols["u"], np.array(cols["t"]), y=cols["y"])
    assert same(y_hat, read_csv(pred_file)["y_hat"])


def test_fit_and_diagnose_match_cli(tmp_path, cli, record_1dof):
    path, _, cols = record_1dof
    t = np.array(cols["t"])
    gb_file = tmp_path / "gb.json"
    p = cli("fit", "--data", path, "--effects", "dynamics", "--out", gb_file, "--json")
    gb = hb.fit(cols["u"], cols["y"], t, effects=["dynamics"])
    assert gb.summary == json.loads(p.stdout)
    cli_params, py_params = json.loads(gb_file.read_text()), gb.params
    for d in (cli_params, py_params):
        # the time, and where the record came from (a file, arrays), may differ
        d["fit"].pop("seconds")
        d["fit"].pop("data_file")
        d["plant"].pop("description")
    assert py_params == cli_params
    p = cli("diagnose", "--data", path, "--model", gb_file, "--json")
    assert hb.diagnose(gb, cols["u"], cols["y"], t) == json.loads(p.stdout)
    p = cli("compare", "--data", path, "--model", gb_file, "--json")
    assert hb.compare(gb, cols["u"], cols["y"], t) == json.loads(p.stdout)


def test_models_cross_between_python_and_cli(tmp_path, cli, record_1dof):
    path, _, cols = record_1dof
    t = np.array(cols["t"])
    # Python -> CLI
    gb = hb.fit(cols["u"], cols["y"], t, effects="hysteresis,dynamics")
    f = tmp_path / "from_python.json"
    gb.save(f)
    p = cli("compare", "--data", path, "--model", f, "--json")
    assert hb.compare(gb, cols["u"], cols["y"], t) == json.loads(p.stdout)
    # CLI -> Python
    nf = tmp_path / "from_cli.json"
    cli("identify", "--data", path, "--epochs", "5", "--out", nf)
    narx = hb.load(nf)
    assert isinstance(narx, hb.Narx)
    pred_file = tmp_path / "pred.csv"
    cli("predict", "--model", nf, "--data", path, "--out", pred_file)
    assert same(narx.predict(cols["u"], t, y=cols["y"]), read_csv(pred_file)["y_hat"])
    # a NARX model saved by Python loads in the CLI and predicts the same
    nf2 = tmp_path / "narx_again.json"
    narx.save(nf2)
    pred2 = tmp_path / "pred2.csv"
    cli("predict", "--model", nf2, "--data", path, "--out", pred2)
    assert read_csv(pred2)["y_hat"] == read_csv(pred_file)["y_hat"]


def test_improve_names_the_hidden_effect():
    """The loop of the tutorial from Python: a plant with hidden creep, a model without it."""
    plant = hb.Plant.builtin("hidden_creep_piezo")
    rec = plant.simulate_scenario("hidden_effect_1khz")
    start = hb.fit(rec.u, rec.y, rec.t, effects="hysteresis,dynamics")
    d = hb.diagnose(start, rec.u, rec.y, rec.t)
    assert d["missing"] == "creep"
    out = hb.improve(start, rec.u, rec.y, rec.t, max_steps=1)
    ladder = out["ladder"]
    assert "creep" in ladder[-1]["effects"]
    assert ladder[-1]["rmse"] < ladder[0]["rmse"] / 3
    assert isinstance(out["model"], hb.GreyBox)
