"""hystbench in Python: simulate, identify, compare, diagnose and improve models of hysteretic
actuators on numpy arrays, on the same Rust library as the ``hystbench`` command line.

Every function mirrors a command and gives the same numbers on the same record::

    import hystbench as hb
    plant = hb.Plant.builtin("bouc_wen_piezo")
    rec = plant.simulate_scenario(hb.Scenario.builtin("seed_1dof"))
    narx = hb.Narx(seed=0).fit(rec.u, rec.y, rec.t)          # hystbench identify
    gb = hb.fit(rec.u, rec.y, rec.t, effects=["hysteresis"])  # hystbench fit
    hb.diagnose(gb, rec.u, rec.y, rec.t)["missing"]           # hystbench diagnose --json

Arrays are float64 of shape (n,) for one signal or (n, k) for k signals; ``ts`` is the
sampling period in seconds or the time stamps (shape (n,)). Errors are raised as ``ValueError``
(``FileNotFoundError`` for a missing file) with the command line's message; what the checks of
``hystbench inspect`` find in a record is issued as a ``RecordWarning``. See docs/python.md.
"""

import json as _json
import os as _os
import warnings as _warnings

import numpy as _np

from . import _hystbench as _core

__version__ = _core.__version__

__all__ = [
    "Plant",
    "Scenario",
    "Record",
    "GreyBox",
    "Narx",
    "fit",
    "compare",
    "diagnose",
    "improve",
    "compensate",
    "load",
    "RecordWarning",
]


class RecordWarning(UserWarning):
    """A finding of the record checks (spikes, clipping, drift...) that did not stop the work."""


def _warn(notes):
    for n in notes:
        _warnings.warn(n, RecordWarning, stacklevel=3)


def _signals(x, what, rows=None):
    """A (k, n) C-contiguous float64 view or copy of (n,) or (n, k) data."""
    try:
        a = _np.asarray(x, dtype=_np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(
            f"{what}: not numbers ({e}); give a float64 array of shape (n,) or (n, k)"
        ) from None
    if a.ndim == 1:
        a = a[None, :]
    elif a.ndim == 2:
        a = a.T
    else:
        raise ValueError(f"{what}: shape {a.shape}; give an array of shape (n,) or (n, k)")
    if rows is not None and a.shape[0] != rows:
        raise ValueError(
            f"{what}: {a.shape[0]} signal(s), the model has {rows}; give shape (n, {rows})"
        )
    return _np.ascontiguousarray(a)


def _time(ts, n):
    """The sampling period as a float, or the time stamps as a float64 array of n values."""
    if isinstance(ts, (int, float, _np.floating, _np.integer)):
        return float(ts)
    t = _signals(ts, "ts")
    if t.shape[0] != 1:
        raise ValueError(f"ts: shape {_np.shape(ts)}; give the time stamps as shape (n,)")
    if t.shape[1] != n:
        raise ValueError(f"ts: {t.shape[1]} time stamps for {n} samples")
    return t[0]


def _shape(cols):
    """One signal as shape (n,), several as (n, k)."""
    if len(cols) == 1:
        return cols[0]
    return _np.column_stack(cols)


def _names(names, prefix, k):
    if names is None:
        return [prefix] if k == 1 else [f"{prefix}{i}" for i in range(1, k + 1)]
    names = [names] if isinstance(names, str) else list(names)
    return names


def _samples(u, y):
    if u.shape[1] != y.shape[1]:
        raise ValueError(f"u has {u.shape[1]} samples, y has {y.shape[1]}; give equal lengths")
    return u.shape[1]


class Record:
    """A simulated record: time ``t``, inputs ``u`` and outputs ``y`` ((n,) or (n, k)), the
    column names and the provenance the command line writes into the sidecar."""

    def __init__(self, t, u, y, inputs, outputs, provenance):
        self.t, self.u, self.y = t, u, y
        self.inputs, self.outputs = inputs, outputs
        self.provenance = provenance

    def __len__(self):
        return len(self.t)

    def __repr__(self):
        return f"Record({len(self)} samples, {','.join(self.inputs)} -> {','.join(self.outputs)})"


class Scenario:
    """An excitation scenario (the JSON of ``scenarios/*.json``)."""

    def __init__(self, text, label="scenario"):
        self.text, self.label = text, label
        _json.loads(text)  # a clear error now rather than at the simulation

    @staticmethod
    def builtin(name):
        """A shipped scenario by name (``seed_1dof``, ``seed_2dof``, ``creep_steps``...)."""
        _, scenarios = _core.builtin_files()
        for file, text in scenarios:
            if file in (name, name + ".json"):
                return Scenario(text, file)
        known = ", ".join(f[: -len(".json")] for f, _ in scenarios)
        raise ValueError(f"unknown built-in scenario `{name}`; known: {known}")

    @staticmethod
    def from_file(path):
        with open(path, encoding="utf-8") as f:
            return Scenario(f.read(), str(path))

    @staticmethod
    def from_dict(d):
        return Scenario(_json.dumps(d), "scenario")

    def to_dict(self):
        return _json.loads(self.text)


class _Model:
    """What every model has: names, effects, prediction, its file."""

    def __init__(self, core):
        self._core = core

    @property
    def inputs(self):
        return self._core.inputs

    @property
    def outputs(self):
        return self._core.outputs

    @property
    def effects(self):
        return self._core.effects

    @property
    def params(self):
        """The model file's content as a dict (parameters, structure, scores)."""
        return _json.loads(self._core.to_json())

    def to_json(self):
        return self._core.to_json()

    def save(self, path, force=False):
        """Write the model file (the command line reads it); an existing file is replaced only
        with ``force=True``."""
        self._core.save(_os.fspath(path), force)

    def predict(self, u, ts, y=None, mode="free_run", outliers="refuse", band=False):
        """The predicted outputs for the inputs ``u`` ((n,) or (n, k)). ``mode="one_step"``
        (NARX only) feeds the measured ``y`` back; a NARX free run starts from the first
        measured samples of ``y`` when given. ``band=True`` also returns the 95 % band's
        half-width (None for models without one)."""
        uu = _signals(u, "u", len(self.inputs))
        yy = None if y is None else _signals(y, "y", len(self.outputs))
        if yy is not None:
            _samples(uu, yy)
        mode = {"free_run": "free-run", "one_step": "one-step"}.get(mode, mode)
        pred, bands, notes = self._core.predict(uu, yy, _time(ts, uu.shape[1]), mode, outliers)
        _warn(notes)
        if not band:
            return _shape(pred)
        half = None if any(b is None for b in bands) else _shape(bands)
        return _shape(pred), half

    def __repr__(self):
        return self._core.describe()


class Plant(_Model):
    """A plant of the effect library (the JSON of ``plants/*.json``): simulate it."""

    @staticmethod
    def builtin(name):
        """A shipped plant by name (``bouc_wen_piezo``, ``piezo_2dof``, ...)."""
        plants, _ = _core.builtin_files()
        for file, text in plants:
            if file in (name, name + ".json"):
                return Plant(_core._Model.parse(file, text))
        known = ", ".join(f[: -len(".json")] for f, _ in plants)
        raise ValueError(f"unknown built-in plant `{name}`; known: {known}")

    @staticmethod
    def builtin_names():
        plants, _ = _core.builtin_files()
        return [f[: -len(".json")] for f, _ in plants]

    @staticmethod
    def from_file(path):
        m = _core._Model.load(_os.fspath(path))
        if m.kind != "plant":
            raise ValueError(f"{path}: a {m.kind} model file, not a plant file")
        return Plant(m)

    @staticmethod
    def from_dict(d, label="plant"):
        return Plant(_core._Model.parse(label, _json.dumps(d)))

    def simulate(self, u, ts, noise=0.0, seed=0):
        """The outputs for the inputs ``u`` at sampling period ``ts`` (or time stamps), with
        white noise of standard deviation ``noise`` from ``seed`` (``simulate --input``)."""
        uu = _signals(u, "u", len(self.inputs))
        return _shape(self._core.simulate(uu, _time(ts, uu.shape[1]), float(noise), int(seed)))

    def simulate_scenario(self, scenario, seed=None):
        """A record of the plant on a scenario (``simulate --scenario``); ``seed`` overrides
        the scenario's."""
        if isinstance(scenario, str):
            scenario = Scenario.builtin(scenario)
        t, u, y, prov = self._core.simulate_scenario(scenario.label, scenario.text, seed)
        return Record(t, _shape(u), _shape(y), self.inputs, self.outputs, _json.loads(prov))


class GreyBox(_Model):
    """A fitted grey-box model (``hystbench fit``); ``summary`` is ``fit --json``'s."""

    def __init__(self, core, summary=None):
        super().__init__(core)
        self.summary = summary


class Narx(_Model):
    """A NARX network (``hystbench identify``), with ``identify``'s settings as keywords:
    ``lags``, ``neurons``, ``layers``, ``epochs``, ``seed``, ``features``, ``greybox``,
    ``ensemble``... (``hystbench identify --help``). ``fit`` trains it; ``scores`` is then
    ``identify --json``'s report."""

    def __init__(self, **settings):
        super().__init__(None)
        if "greybox" in settings and isinstance(settings["greybox"], str):
            settings["greybox"] = settings["greybox"] != "off"
        if "features" in settings and isinstance(settings["features"], str):
            settings["features"] = settings["features"].split(",")
        self.settings = settings
        self.scores = None

    def fit(self, u, y, ts, test=None, inputs=None, outputs=None, outliers="refuse"):
        """Train on the first half of the record and score on the second (as ``identify``),
        or train on it all and score on ``test = (u_test, y_test, ts_test)``. Returns self."""
        uu, yy = _signals(u, "u"), _signals(y, "y")
        n = _samples(uu, yy)
        ins = _names(inputs, "u", uu.shape[0])
        outs = _names(outputs, "y", yy.shape[0])
        te = None
        if test is not None:
            ut, yt, tt = test
            ut, yt = _signals(ut, "test u", uu.shape[0]), _signals(yt, "test y", yy.shape[0])
            te = (ut, yt, _time(tt, _samples(ut, yt)))
        core, report, notes = _core.identify(
            uu, yy, _time(ts, n), ins, outs, self.settings, te, outliers
        )
        _warn(notes)
        self._core = core
        self.scores = _json.loads(report)
        return self

    @staticmethod
    def load(path):
        m = _core._Model.load(_os.fspath(path))
        if m.kind != "narx":
            raise ValueError(f"{path}: a {m.kind} file, not a NARX model file")
        return _wrap(m)

    def _fitted(self):
        if self._core is None:
            raise ValueError("this Narx is not trained yet: call .fit(u, y, ts) first")

    def predict(self, u, ts, y=None, mode="free_run", outliers="refuse", band=False):
        self._fitted()
        return super().predict(u, ts, y=y, mode=mode, outliers=outliers, band=band)

    def save(self, path, force=False):
        self._fitted()
        super().save(path, force)

    def __repr__(self):
        if self._core is None:
            return f"Narx(untrained, {self.settings})"
        return self._core.describe()


def _wrap(core):
    """The Python class of a loaded model."""
    if core.kind == "narx":
        n = Narx()
        n._core = core
        return n
    return Plant(core) if core.kind == "plant" else GreyBox(core)


def load(path):
    """Any model file: a plant, a grey-box model or a NARX model."""
    return _wrap(_core._Model.load(_os.fspath(path)))


def _effects(effects):
    return effects if isinstance(effects, str) else ",".join(effects)


def fit(u, y, ts, effects, inputs=None, outputs=None, train_fraction=None, plays=None,
        outliers="refuse"):
    """A grey-box model of the effects (``["hysteresis", "creep", "dynamics"]`` or
    ``"hysteresis,creep"``) fitted to the record (``hystbench fit``)."""
    uu, yy = _signals(u, "u"), _signals(y, "y")
    n = _samples(uu, yy)
    core, summary, notes = _core.fit(
        uu, yy, _time(ts, n), _names(inputs, "u", uu.shape[0]), _names(outputs, "y", yy.shape[0]),
        _effects(effects), train_fraction, plays, outliers,
    )
    _warn(notes)
    return GreyBox(core, _json.loads(summary))


def _record(model, u, y):
    uu = _signals(u, "u", len(model.inputs))
    yy = _signals(y, "y", len(model.outputs))
    return uu, yy, _samples(uu, yy)


def compare(model, u, y, ts, outliers="refuse"):
    """Scores and where the model fails on the record: ``compare --json``'s dict."""
    uu, yy, n = _record(model, u, y)
    report, notes = _core.compare(model._core, uu, yy, _time(ts, n), outliers)
    _warn(notes)
    return _json.loads(report)


def diagnose(model, u, y, ts, refit=True, outliers="refuse"):
    """Which physical effect the model misses: ``diagnose --json``'s dict (``missing``,
    ``ranking``, per-output messages...)."""
    uu, yy, n = _record(model, u, y)
    report, notes = _core.diagnose(model._core, uu, yy, _time(ts, n), bool(refit), outliers)
    _warn(notes)
    return _json.loads(report)


def improve(model, u, y, ts, max_steps=4, train_fraction=None, outliers="refuse"):
    """The improvement loop from a grey-box model or a plant: ``improve --json``'s dict
    (``ladder``), with ``models`` (the model of each rung, None for the start) and ``model``
    (the last one)."""
    uu, yy, n = _record(model, u, y)
    report, models, notes = _core.improve(
        model._core, uu, yy, _time(ts, n), int(max_steps), train_fraction, outliers
    )
    _warn(notes)
    out = _json.loads(report)
    out["models"] = [None if m is None else GreyBox(m) for m in models]
    last = [m for m in out["models"] if m is not None]
    out["model"] = last[-1] if last else model
    return out


def compensate(model, reference, ts, limits=None):
    """The input that makes the model follow ``reference`` (one signal per output), as
    ``hystbench compensate``: a dict with ``u`` (the input), ``y`` (the model's output under
    it), ``delay`` (the preview taken), ``relative_degree``, ``clipped`` and
    ``unreachable``."""
    r = _signals(reference, "reference", len(model.outputs))
    lim = [None] * len(model.inputs) if limits is None else [
        None if l is None else (float(l[0]), float(l[1])) for l in limits
    ]
    u, y, rest = _core.compensate(model._core, r, float(ts), lim)
    out = _json.loads(rest)
    out["u"], out["y"] = _shape(u), _shape(y)
    return out
