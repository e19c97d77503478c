//! `hystbench._hystbench`: the Python extension over the hystbench library (PyO3).
//!
//! Thin on purpose: every function here builds a record from arrays, calls the library function
//! that the matching command of the command line calls, and hands back arrays and the command's
//! `--json` text. The Python package (`python/hystbench/__init__.py`) shapes the arrays and
//! turns the JSON into dicts. Long work runs with the interpreter's lock released.

use hystbench::data::inspect::{screened, Outliers};
use hystbench::data::{IoRecord, Record};
use hystbench::model::{LoadedModel, Model};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;
use std::path::Path;

/// A library error as a Python exception with the command line's words: `FileNotFoundError`
/// for a missing file, `ValueError` otherwise.
fn py_err(e: impl Into<anyhow::Error>) -> PyErr {
    let e: anyhow::Error = e.into();
    let msg = hystbench::error_message(&e);
    let missing = e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::NotFound)
    });
    if missing {
        PyFileNotFoundError::new_err(msg)
    } else {
        PyValueError::new_err(msg)
    }
}

/// A value error with a message.
fn value_err(msg: String) -> PyErr {
    PyValueError::new_err(msg)
}

/// Rows of a (k, n) array: one signal per row.
fn rows(a: &PyReadonlyArray2<'_, f64>) -> Vec<Vec<f64>> {
    a.as_array()
        .rows()
        .into_iter()
        .map(|r| r.to_vec())
        .collect()
}

/// Arrays for Python, without copying the values.
fn arrays<'py>(py: Python<'py>, cols: Vec<Vec<f64>>) -> Vec<Bound<'py, PyArray1<f64>>> {
    cols.into_iter()
        .map(|c| PyArray1::from_vec(py, c))
        .collect()
}

/// The time stamps of `n` samples: `time` is a sampling period in seconds (the stamps are
/// k * ts, as a record written by `simulate`) or the stamps themselves.
fn time_stamps(time: &Bound<'_, PyAny>, n: usize) -> PyResult<Vec<f64>> {
    if let Ok(ts) = time.extract::<f64>() {
        if !(ts.is_finite() && ts > 0.0) {
            return Err(value_err(format!(
                "ts = {ts}: the sampling period must be a finite number > 0 (seconds)"
            )));
        }
        return Ok((0..n).map(|k| 0.0 + k as f64 * ts).collect());
    }
    let t: PyReadonlyArray1<'_, f64> = time.extract().map_err(|_| {
        value_err(
            "ts: give the sampling period in seconds (a number) or the time stamps (a float64 array of shape (n,))"
                .into(),
        )
    })?;
    Ok(t.as_array().to_vec())
}

/// The columns of a record made of arrays: named inputs, then named outputs.
fn named(names: &[String], values: Vec<Vec<f64>>, what: &str) -> PyResult<Vec<(String, Vec<f64>)>> {
    if names.len() != values.len() {
        return Err(value_err(format!(
            "{what}: {} column(s) given, {} name(s) ({}); give one column per name",
            values.len(),
            names.len(),
            names.join(", ")
        )));
    }
    Ok(names.iter().cloned().zip(values).collect())
}

/// A record made of arrays, screened as a modelling command screens a file: returns the
/// selected record and the findings to warn of (one line each).
#[allow(clippy::too_many_arguments)]
fn record(
    label: &str,
    u: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
    time: &Bound<'_, PyAny>,
    inputs: &[String],
    outputs: &[String],
    outputs_required: bool,
    outliers: &str,
) -> PyResult<(IoRecord, Vec<String>)> {
    let policy: Outliers = outliers.parse().map_err(value_err)?;
    let n = u.first().or(y.first()).map_or(0, Vec::len);
    let t = time_stamps(time, n)?;
    let mut cols = named(inputs, u, "u")?;
    cols.extend(named(outputs, y, "y")?);
    let rec = Record::from_arrays(label, t, cols).map_err(py_err)?;
    let (io, s) = screened(rec, policy, |r| {
        IoRecord::from_record(r, Some(inputs), Some(outputs), outputs_required)
    })
    .map_err(py_err)?;
    let mut notes: Vec<String> = s
        .findings
        .iter()
        .map(|f| format!("{label}: {}", f.summary()))
        .collect();
    if s.repaired > 0 {
        notes.push(format!(
            "{label}: {} outlier(s) repaired (each replaced by the line between its good neighbours), lines {:?}",
            s.repaired, s.repaired_lines
        ));
    }
    Ok((io, notes))
}

/// A model of the library: a plant, a fitted grey-box model or a NARX model.
#[pyclass(name = "_Model", module = "hystbench._hystbench", frozen)]
pub struct PyModel {
    inner: LoadedModel,
}

impl PyModel {
    fn model(&self) -> &dyn Model {
        self.inner.as_model()
    }

    fn plant(&self) -> PyResult<&hystbench::plant::Plant> {
        match &self.inner {
            LoadedModel::Plant(p) => Ok(p),
            _ => Err(value_err(format!(
                "{}: only a plant simulates; this is a fitted model (predict with it)",
                self.model().describe()
            ))),
        }
    }

    /// A record for this model from arrays (its own column names).
    fn record(
        &self,
        u: PyReadonlyArray2<'_, f64>,
        y: Option<PyReadonlyArray2<'_, f64>>,
        time: &Bound<'_, PyAny>,
        outliers: &str,
    ) -> PyResult<(IoRecord, Vec<String>)> {
        let m = self.model();
        let outputs = if y.is_some() {
            m.output_names()
        } else {
            Vec::new()
        };
        record(
            "arrays",
            rows(&u),
            y.as_ref().map(rows).unwrap_or_default(),
            time,
            &m.input_names(),
            &outputs,
            y.is_some(),
            outliers,
        )
    }
}

#[pymethods]
impl PyModel {
    /// Parse a model file's text (plant, grey-box or NARX); `label` names it in errors.
    #[staticmethod]
    fn parse(label: &str, text: &str) -> PyResult<PyModel> {
        Ok(PyModel {
            inner: LoadedModel::parse(Path::new(label), text).map_err(py_err)?,
        })
    }

    /// Read a model file (plant, grey-box or NARX).
    #[staticmethod]
    fn load(path: &str) -> PyResult<PyModel> {
        Ok(PyModel {
            inner: LoadedModel::load(Path::new(path)).map_err(py_err)?,
        })
    }

    /// `plant`, `greybox` or `narx`.
    #[getter]
    fn kind(&self) -> &'static str {
        match self.inner {
            LoadedModel::Plant(_) => "plant",
            LoadedModel::GreyBox(_) => "greybox",
            LoadedModel::Narx(_) => "narx",
        }
    }

    #[getter]
    fn inputs(&self) -> Vec<String> {
        self.model().input_names()
    }

    #[getter]
    fn outputs(&self) -> Vec<String> {
        self.model().output_names()
    }

    #[getter]
    fn effects(&self) -> Vec<String> {
        self.model()
            .effects()
            .iter()
            .map(|e| e.as_str().to_string())
            .collect()
    }

    #[getter]
    fn sampling_period(&self) -> Option<f64> {
        self.model().sampling_period()
    }

    fn describe(&self) -> String {
        self.model().describe()
    }

    /// The text of its file.
    fn to_json(&self) -> PyResult<String> {
        self.inner.to_json().map_err(py_err)
    }

    /// Write its file (refusing to replace one unless `force`), atomically.
    fn save(&self, path: &str, force: bool) -> PyResult<()> {
        let text = self.inner.to_json().map_err(py_err)?;
        hystbench::data::write_atomic(Path::new(path), text.as_bytes(), force).map_err(py_err)
    }

    /// Free-run (or, for a NARX model, one-step-ahead with the measured `y`) prediction:
    /// (predictions, band half-widths or None per output, notes).
    #[pyo3(signature = (u, y, time, mode, outliers))]
    #[allow(clippy::type_complexity)]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        u: PyReadonlyArray2<'py, f64>,
        y: Option<PyReadonlyArray2<'py, f64>>,
        time: &Bound<'py, PyAny>,
        mode: &str,
        outliers: &str,
    ) -> PyResult<(
        Vec<Bound<'py, PyArray1<f64>>>,
        Vec<Option<Bound<'py, PyArray1<f64>>>>,
        Vec<String>,
    )> {
        let mode: hystbench::narx::Mode = mode.parse().map_err(value_err)?;
        let (io, notes) = self.record(u, y, time, outliers)?;
        let (pred, bands) = match &self.inner {
            LoadedModel::Narx(m) => {
                let preds = py.detach(|| m.predict(&io, mode)).map_err(py_err)?;
                let mut p = Vec::new();
                let mut b = Vec::new();
                for o in preds {
                    if let Some(k) = o.diverged_at {
                        return Err(py_err(hystbench::model::ModelError::FreeRunDiverged {
                            output: o.name,
                            sample: k,
                        }));
                    }
                    p.push(o.values);
                    b.push(o.half_width);
                }
                (p, b)
            }
            _ => {
                if mode != hystbench::narx::Mode::FreeRun {
                    return Err(value_err(format!(
                        "mode `{}`: {} predicts in free run only",
                        mode.as_str(),
                        self.model().describe()
                    )));
                }
                let inner = &self.inner;
                let p = py
                    .detach(|| hystbench::model::predict_finite(inner.as_model(), &io))
                    .map_err(py_err)?;
                let n = p.len();
                (p, vec![None; n])
            }
        };
        let bands = bands
            .into_iter()
            .map(|b| b.map(|h| PyArray1::from_vec(py, h)))
            .collect();
        Ok((arrays(py, pred), bands, notes))
    }

    /// Simulate this plant driven by the inputs `u` with white noise of standard deviation
    /// `noise` from `seed` (as `simulate --input`): the outputs.
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: PyReadonlyArray2<'py, f64>,
        time: &Bound<'py, PyAny>,
        noise: f64,
        seed: u64,
    ) -> PyResult<Vec<Bound<'py, PyArray1<f64>>>> {
        let plant = self.plant()?;
        if !(noise.is_finite() && noise >= 0.0) {
            return Err(value_err(format!(
                "noise = {noise}: must be a finite number >= 0"
            )));
        }
        let (io, _) = record(
            "arrays",
            rows(&u),
            Vec::new(),
            time,
            &plant.inputs,
            &[],
            false,
            "keep",
        )?;
        let sim = py
            .detach(|| hystbench::simulator::simulate_recorded(plant, &io, noise, seed))
            .map_err(py_err)?;
        let ys = sim.record.outputs.into_iter().map(|s| s.values).collect();
        Ok(arrays(py, ys))
    }

    /// Simulate this plant on a scenario (its file text; `label` names it in errors) as
    /// `simulate --scenario` does: (t, inputs, outputs, the sidecar's JSON).
    #[pyo3(signature = (label, text, seed=None))]
    #[allow(clippy::type_complexity)]
    fn simulate_scenario<'py>(
        &self,
        py: Python<'py>,
        label: &str,
        text: &str,
        seed: Option<u64>,
    ) -> PyResult<(
        Bound<'py, PyArray1<f64>>,
        Vec<Bound<'py, PyArray1<f64>>>,
        Vec<Bound<'py, PyArray1<f64>>>,
        String,
    )> {
        let plant = self.plant()?;
        let path = Path::new(label);
        let scenario = hystbench::scenario::ScenarioSpec::parse(path, text)
            .and_then(|s| s.check(path))
            .map_err(py_err)?;
        let sim = py
            .detach(|| hystbench::simulator::simulate_scenario(plant, &scenario, seed))
            .map_err(py_err)?;
        let t = sim.record.time();
        let provenance = serde_json::to_string(&sim.provenance).map_err(py_err)?;
        let us = sim.record.inputs.into_iter().map(|s| s.values).collect();
        let ys = sim.record.outputs.into_iter().map(|s| s.values).collect();
        Ok((
            PyArray1::from_vec(py, t),
            arrays(py, us),
            arrays(py, ys),
            provenance,
        ))
    }
}

/// Files by (name, text).
type Files = Vec<(String, String)>;

/// The shipped plants and scenarios: (file name, text), each once.
#[pyfunction]
fn builtin_files() -> (Files, Files) {
    let mut plants = Vec::new();
    let mut scenarios: Files = Vec::new();
    for &(p, ptext, s, stext) in hystbench::plant::builtin::BUILTIN {
        plants.push((p.to_string(), ptext.to_string()));
        if !scenarios.iter().any(|(n, _)| n == s) {
            scenarios.push((s.to_string(), stext.to_string()));
        }
    }
    (plants, scenarios)
}

/// `fit`: a grey-box model of `effects` (comma-separated) fitted to the record: (model, the
/// `--json` summary, notes).
#[pyfunction]
#[pyo3(signature = (u, y, time, inputs, outputs, effects, train_fraction, plays, outliers))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    u: PyReadonlyArray2<'_, f64>,
    y: PyReadonlyArray2<'_, f64>,
    time: &Bound<'_, PyAny>,
    inputs: Vec<String>,
    outputs: Vec<String>,
    effects: &str,
    train_fraction: Option<f64>,
    plays: Option<usize>,
    outliers: &str,
) -> PyResult<(PyModel, String, Vec<String>)> {
    let cfg = hystbench::graybox::GreyBoxConfig::from_effect_list(effects)
        .and_then(|c| c.with_fit_options(plays, train_fraction))
        .map_err(py_err)?;
    let (io, notes) = record(
        "arrays",
        rows(&u),
        rows(&y),
        time,
        &inputs,
        &outputs,
        true,
        outliers,
    )?;
    let model = py.detach(|| cfg.fit(&io)).map_err(py_err)?;
    let summary = model.summary_json().to_string();
    Ok((
        PyModel {
            inner: LoadedModel::GreyBox(model),
        },
        summary,
        notes,
    ))
}

/// `identify`: a NARX model of the record (its first half trains, its second tests, unless
/// a test record is given): (model, the `--json` report, notes).
#[pyfunction]
#[pyo3(signature = (u, y, time, inputs, outputs, settings, test, outliers))]
#[allow(clippy::too_many_arguments)]
fn identify(
    py: Python<'_>,
    u: PyReadonlyArray2<'_, f64>,
    y: PyReadonlyArray2<'_, f64>,
    time: &Bound<'_, PyAny>,
    inputs: Vec<String>,
    outputs: Vec<String>,
    settings: &Bound<'_, pyo3::types::PyDict>,
    test: Option<(
        PyReadonlyArray2<'_, f64>,
        PyReadonlyArray2<'_, f64>,
        Bound<'_, PyAny>,
    )>,
    outliers: &str,
) -> PyResult<(PyModel, String, Vec<String>)> {
    let s = narx_settings(settings)?;
    let (data, mut notes) = record(
        "arrays",
        rows(&u),
        rows(&y),
        time,
        &inputs,
        &outputs,
        true,
        outliers,
    )?;
    let (train, test, split) = match test {
        None => {
            let (a, b) = data.split_halves();
            (a, b, true)
        }
        Some((ut, yt, tt)) => {
            let (te, more) = record(
                "test arrays",
                rows(&ut),
                rows(&yt),
                &tt,
                &inputs,
                &outputs,
                true,
                outliers,
            )?;
            notes.extend(more);
            (data, te, false)
        }
    };
    let cfg = s.config(&train).map_err(py_err)?;
    let (model, report) = py
        .detach(|| -> anyhow::Result<_> {
            let (model, eval) = cfg.identify(&train, &test, split)?;
            let report = model.report_json(&eval, &model.outside(&test));
            Ok((model, report))
        })
        .map_err(py_err)?;
    Ok((
        PyModel {
            inner: LoadedModel::Narx(model),
        },
        report.to_string(),
        notes,
    ))
}

/// The library's settings from the keywords of `Narx(...)` (unknown ones refused).
fn narx_settings(d: &Bound<'_, pyo3::types::PyDict>) -> PyResult<hystbench::narx::NarxSettings> {
    use hystbench::narx::NarxSettings;
    let mut s = NarxSettings::default();
    for (k, v) in d.iter() {
        let key: String = k.extract()?;
        let bad = |e: PyErr| value_err(format!("Narx({key}=...): {e}"));
        let named = |v: &Bound<'_, PyAny>| -> PyResult<String> { v.extract::<String>() };
        match key.as_str() {
            "lags" => s.lags = v.extract().map_err(bad)?,
            "output_lags" => s.output_lags = v.extract().map_err(bad)?,
            "input_lags" => s.input_lags = v.extract().map_err(bad)?,
            "delay" => s.delay = v.extract().map_err(bad)?,
            "neurons" => s.neurons = v.extract().map_err(bad)?,
            "layers" => s.layers = v.extract().map_err(bad)?,
            "lr" => s.lr = v.extract().map_err(bad)?,
            "batch" => s.batch = v.extract().map_err(bad)?,
            "epochs" => s.epochs = v.extract().map_err(bad)?,
            "seed" => s.seed = v.extract().map_err(bad)?,
            "restarts" => s.restarts = v.extract().map_err(bad)?,
            "sim_steps" => s.sim_steps = v.extract().map_err(bad)?,
            "sim_lr" => s.sim_lr = v.extract().map_err(bad)?,
            "window" => s.window = v.extract().map_err(bad)?,
            "sim_patience" => s.sim_patience = v.extract().map_err(bad)?,
            "weight_decay" => s.weight_decay = v.extract().map_err(bad)?,
            "validation_fraction" => s.validation_fraction = v.extract().map_err(bad)?,
            "ensemble" => s.ensemble = v.extract().map_err(bad)?,
            "features" => s.features = v.extract().map_err(bad)?,
            "greybox" => s.greybox = v.extract().map_err(bad)?,
            "interaction" => {
                s.interaction = Some(named(&v).map_err(bad)?.parse().map_err(value_err)?)
            }
            "optimizer" => s.optimizer = Some(named(&v).map_err(bad)?.parse().map_err(value_err)?),
            "protocol" => s.protocol = named(&v).map_err(bad)?.parse().map_err(value_err)?,
            other => {
                return Err(value_err(format!(
                    "Narx({other}=...): unknown setting; the settings are those of `hystbench identify --help`"
                )))
            }
        }
    }
    Ok(s)
}

/// `compare`: the `--json` report and notes.
#[pyfunction]
fn compare(
    py: Python<'_>,
    model: &PyModel,
    u: PyReadonlyArray2<'_, f64>,
    y: PyReadonlyArray2<'_, f64>,
    time: &Bound<'_, PyAny>,
    outliers: &str,
) -> PyResult<(String, Vec<String>)> {
    let (io, notes) = model.record(u, Some(y), time, outliers)?;
    let inner = &model.inner;
    let report = py
        .detach(|| -> anyhow::Result<_> {
            let m = inner.as_model();
            let pred = hystbench::model::predict_finite(m, &io)?;
            Ok(hystbench::diagnose::compare::compare_model(m, &io, &pred)?)
        })
        .map_err(py_err)?;
    Ok((report.to_json(), notes))
}

/// `diagnose`: the `--json` diagnosis and notes.
#[pyfunction]
fn diagnose(
    py: Python<'_>,
    model: &PyModel,
    u: PyReadonlyArray2<'_, f64>,
    y: PyReadonlyArray2<'_, f64>,
    time: &Bound<'_, PyAny>,
    refit: bool,
    outliers: &str,
) -> PyResult<(String, Vec<String>)> {
    let (io, notes) = model.record(u, Some(y), time, outliers)?;
    let inner = &model.inner;
    let config = inner.structure();
    let d = py
        .detach(|| -> anyhow::Result<_> {
            let m = inner.as_model();
            let pred = hystbench::model::predict_finite(m, &io)?;
            let mut opts = hystbench::diagnose::DiagnoseOptions::default();
            if !refit {
                opts.refit = None;
            }
            Ok(hystbench::diagnose::diagnose_any(
                &io,
                &pred,
                &m.effects(),
                config.as_ref(),
                &opts,
            ))
        })
        .map_err(py_err)?;
    Ok((serde_json::to_string(&d).map_err(py_err)?, notes))
}

/// `improve`: the `--json` ladder, the model of each rung (None for the start) and notes.
#[pyfunction]
#[pyo3(signature = (model, u, y, time, max_steps, train_fraction, outliers))]
#[allow(clippy::too_many_arguments)]
fn improve(
    py: Python<'_>,
    model: &PyModel,
    u: PyReadonlyArray2<'_, f64>,
    y: PyReadonlyArray2<'_, f64>,
    time: &Bound<'_, PyAny>,
    max_steps: usize,
    train_fraction: Option<f64>,
    outliers: &str,
) -> PyResult<(String, Vec<Option<PyModel>>, Vec<String>)> {
    let config = model.inner.structure().ok_or_else(|| {
        value_err(format!(
            "{}: the loop refits a grey-box model or a plant's structure; start from one (hystbench.fit or a plant)",
            model.model().describe()
        ))
    })?;
    let opts = hystbench::improve::ImproveOptions {
        max_steps,
        train_fraction,
        ..Default::default()
    };
    opts.check().map_err(py_err)?;
    let (io, notes) = model.record(u, Some(y), time, outliers)?;
    // the loop owns its starting model: a copy of this one
    let text = model.inner.to_json().map_err(py_err)?;
    let ladder = py
        .detach(|| -> anyhow::Result<_> {
            let start = LoadedModel::parse(Path::new("model"), &text)?.into_model();
            Ok(hystbench::improve::improve(
                start,
                config,
                &io,
                &opts,
                &mut |_| {},
            )?)
        })
        .map_err(py_err)?;
    let json =
        serde_json::to_string(&serde_json::json!({ "ladder": ladder.rungs })).map_err(py_err)?;
    let models = ladder
        .rungs
        .into_iter()
        .map(|r| {
            r.model.map(|m| PyModel {
                inner: LoadedModel::GreyBox(m),
            })
        })
        .collect();
    Ok((json, models, notes))
}

/// `compensate`: the inputs that make the model follow `reference` (one row per output),
/// the model's output under them, and the rest of the result as JSON.
#[pyfunction]
#[pyo3(signature = (model, reference, ts, limits))]
#[allow(clippy::type_complexity)]
fn compensate<'py>(
    py: Python<'py>,
    model: &PyModel,
    reference: PyReadonlyArray2<'py, f64>,
    ts: f64,
    limits: Vec<Option<(f64, f64)>>,
) -> PyResult<(
    Vec<Bound<'py, PyArray1<f64>>>,
    Vec<Bound<'py, PyArray1<f64>>>,
    String,
)> {
    if !(ts.is_finite() && ts > 0.0) {
        return Err(value_err(format!(
            "ts = {ts}: the sampling period must be a finite number > 0 (seconds)"
        )));
    }
    let r = rows(&reference);
    if let Some((i, k)) = r
        .iter()
        .enumerate()
        .find_map(|(i, c)| c.iter().position(|v| !v.is_finite()).map(|k| (i, k)))
    {
        return Err(value_err(format!(
            "reference: row {k} of output {i} is not finite (NaN or infinity are not allowed)"
        )));
    }
    let refs: Vec<&[f64]> = r.iter().map(Vec::as_slice).collect();
    let opts = hystbench::compensate::CompensateOptions {
        limits,
        ..Default::default()
    };
    let inner = &model.inner;
    let c = py
        .detach(|| hystbench::compensate::compensate(inner.as_model(), &refs, ts, &opts))
        .map_err(py_err)?;
    let rest = serde_json::json!({
        "delay": c.delay,
        "relative_degree": c.relative_degree,
        "seeded": c.seeded,
        "clipped": c.clipped,
        "unreachable": c.unreachable,
    });
    Ok((
        arrays(py, c.inputs),
        arrays(py, c.model_output),
        rest.to_string(),
    ))
}

#[pymodule]
fn _hystbench(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyModel>()?;
    m.add_function(wrap_pyfunction!(builtin_files, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(improve, m)?)?;
    m.add_function(wrap_pyfunction!(compensate, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
