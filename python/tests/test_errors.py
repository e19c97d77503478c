"""Bad input raises a Python exception with the command line's words; nothing crashes."""

import json

import numpy as np
import pytest

import hystbench as hb

N = 400


@pytest.fixture(scope="module")
def rec():
    plant = hb.Plant.builtin("bouc_wen_piezo")
    u = 40 * np.sin(np.linspace(0, 12 * np.pi, N)) + 50
    return u, plant.simulate(u, 1e-4)


def test_wrong_shapes(rec):
    u, y = rec
    with pytest.raises(ValueError, match=r"shape \(2, 2, 100\)"):
        hb.fit(np.zeros((2, 2, 100)), y, 1e-4, effects="dynamics")
    with pytest.raises(ValueError, match="u has 400 samples, y has 399"):
        hb.fit(u, y[:-1], 1e-4, effects="dynamics")
    with pytest.raises(ValueError, match="the model has 1"):
        hb.Plant.builtin("bouc_wen_piezo").simulate(np.zeros((N, 2)), 1e-4)


def test_nan_is_refused_with_the_line(rec):
    u, y = rec
    y = y.copy()
    y[17] = np.nan
    with pytest.raises(ValueError, match=r"line 19, column `y`: `NaN` is not finite"):
        hb.fit(u, y, 1e-4, effects="dynamics")


def test_strings_are_refused(rec):
    _, y = rec
    with pytest.raises(ValueError, match="u: not numbers"):
        hb.fit(["a", "b"] * (N // 2), y, 1e-4, effects="dynamics")


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="no_such_model.json"):
        hb.load("no_such_model.json")
    with pytest.raises(FileNotFoundError):
        hb.Plant.from_file("no_such_plant.json")


def test_model_of_another_version(tmp_path, rec):
    u, y = rec
    narx = hb.Narx(epochs=2, ensemble=1, restarts=1, greybox=False).fit(u, y, 1e-4)
    d = json.loads(narx.to_json())
    d["version"] = 999
    f = tmp_path / "future.json"
    f.write_text(json.dumps(d))
    with pytest.raises(ValueError, match="version 999 is not supported"):
        hb.load(f)


def test_bad_settings_and_effects(rec):
    u, y = rec
    with pytest.raises(ValueError, match="unknown effect `magic`"):
        hb.fit(u, y, 1e-4, effects="magic")
    with pytest.raises(ValueError, match="unknown setting"):
        hb.Narx(neurones=3).fit(u, y, 1e-4)
    with pytest.raises(ValueError, match="sampling period must be a finite number > 0"):
        hb.fit(u, y, -1.0, effects="dynamics")
    with pytest.raises(ValueError, match="not trained yet"):
        hb.Narx().predict(u, 1e-4)


def test_gross_outlier_is_refused_then_repaired(rec):
    u, y = rec
    y = y.copy()
    y[200] = 1e6
    with pytest.raises(ValueError, match=r"line 202, column `y`: 1e6 is a gross outlier"):
        hb.fit(u, y, 1e-4, effects="dynamics")
    with pytest.warns(hb.RecordWarning, match="repaired"):
        hb.fit(u, y, 1e-4, effects="dynamics", outliers="repair")


def test_no_overwrite_without_force(tmp_path, rec):
    u, y = rec
    gb = hb.fit(u, y, 1e-4, effects="dynamics")
    f = tmp_path / "gb.json"
    gb.save(f)
    with pytest.raises(ValueError, match="--force"):
        gb.save(f)
    gb.save(f, force=True)
