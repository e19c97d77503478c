"""A fresh install works with no data files beside it: shipped plants and scenarios by name."""

import os

import numpy as np

import hystbench as hb


def test_builtin_plant_simulates_anywhere(tmp_path):
    os.chdir(tmp_path)
    phase = np.linspace(0, 8 * np.pi, 2000)
    u = 50 + 40 * np.sin(phase)
    y = hb.Plant.builtin("bouc_wen_piezo").simulate(u, 1e-4)
    assert y.shape == (2000,) and np.all(np.isfinite(y))
    # a hysteresis loop: at mid-input (second period) the descending branch lies above the
    # ascending one by a share of the output's range
    up, down = np.argmin(abs(phase - 2 * np.pi)), np.argmin(abs(phase - 3 * np.pi))
    assert abs(u[up] - u[down]) < 0.5
    assert y[down] - y[up] > 0.05 * np.ptp(y)
    assert set(hb.Plant.builtin_names()) >= {"bouc_wen_piezo", "piezo_2dof"}


def test_builtin_2dof_record():
    rec = hb.Plant.builtin("piezo_2dof").simulate_scenario("seed_2dof")
    assert rec.u.shape == (len(rec), 2) and rec.y.shape == (len(rec), 2)
    assert rec.inputs == ["u1", "u2"]
