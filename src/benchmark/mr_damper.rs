//! # MR damper study: train on sine tests, test on an earthquake record
//!
//! Measured magnetorheological damper (UTFSM data, `mr-damper-utfsm/README.md`), driven in
//! displacement x (mm), force F (N) measured, at several coil currents I (A).
//!
//! Protocol (fixed, printed by the command):
//! - training: the ten 1 ms sine records (10 mm at 1 Hz and 5 mm at 3 Hz, at 0, 0.25, 0.5,
//!   0.75 and 1.0 A). The 5 ms sine records are not used: records of different sampling
//!   periods are refused together ([`check_sampling_periods`]) rather than silently resampled;
//! - test: the earthquake record (1 ms, 64,648 samples), one free run from rest per current
//!   0.2, 0.4, 0.6, 0.8, 1.0 A (none of them is a training current except 1.0 A), scored over
//!   the whole record: R^2 and RMS error in N;
//! - every model is run from rest on each record separately: no state, regressor or window ever
//!   crosses a record boundary.
//!
//! Grey-box: F = c0 dx/dt + k0 x + alpha g + f0, dx/dt the library's viscous operator (backward
//! difference), g either the library's Bouc-Wen state on x (n = 1, A = 1, mm; Spencer's simple
//! Bouc-Wen model, [`Structure::BoucWen`]) or tanh((dx/dt) / v0) (a smoothed Bingham plastic,
//! [`Structure::Bingham`]). For fixed (B, Gamma) or v0 the model is linear in
//! (c0, k0, alpha, f0): least squares inside, Nelder-Mead or golden section outside (variable
//! projection). Two ways to cover the currents:
//! - `scheduled`: one model for all currents, (B, Gamma) or v0 shared and c0, k0, alpha, f0
//!   affine in I (Spencer et al.'s c0 = c0a + c0b u, alpha = alpha_a + alpha_b u);
//! - `per-current`: one model per training current, every parameter interpolated linearly in I
//!   between the two neighbouring training currents.
//!
//! The headline grey-box is the scheduled structure with the lowest leave-one-test-out error on
//! the training records ([`cross_validate`]); the test record plays no part in the choice.
//!
//! NARX: inputs x and I (a constant column), output F, trained on the ten records at once
//! ([`NarxConfig::fit_records`]) after subsampling every record by [`NARX_DECIMATION`] (1 ms ->
//! 10 ms: at 1 ms the lags would cover only a few ms of a 1-3 Hz motion; the records' moving
//! averages of >= 33 samples already remove what 10 ms cannot carry). Scored on the earthquake
//! record subsampled the same way.
//!
//! ## References
//! - B. F. Spencer Jr., S. J. Dyke, M. K. Sain, J. D. Carlson, "Phenomenological model for
//!   magnetorheological dampers", J. Eng. Mech. 123(3):230-238, 1997.
//! - J. A. Nelder, R. Mead, "A simplex method for function minimization", Comput. J.
//!   7(4):308-313, 1965.
//! - G. H. Golub, V. Pereyra, SIAM J. Numer. Anal. 10(2):413-432, 1973 (variable projection).
//! - Data: D. Maurel, M. Quiroz, github.com/DanielMaurelE/vRTHS_AMBC_MRdamper (MIT).

use crate::data::{read_csv, DataError, IoRecord, Record, Signal};
use crate::effect::bouc_wen::BoucWenSpec;
use crate::effect::viscous::rate;
use crate::effect::Operator;
use crate::metrics;
use crate::narx::{FittedNarx, Interaction, Lags, Mode, NarxConfig, NarxError};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The test record.
pub const EARTHQUAKE_FILE: &str = "earthquake_validation.csv";
/// Its header.
pub const EARTHQUAKE_COLUMNS: [&str; 7] = [
    "t_s",
    "x_mm",
    "F_I0.2A_N",
    "F_I0.4A_N",
    "F_I0.6A_N",
    "F_I0.8A_N",
    "F_I1.0A_N",
];
/// Currents of the earthquake record's force columns (A), in column order.
pub const TEST_CURRENTS: [f64; 5] = [0.2, 0.4, 0.6, 0.8, 1.0];
/// Header of every sine record.
pub const SINE_COLUMNS: [&str; 5] = ["t_s", "x_mm", "v_mm_s", "F_N", "I_A"];
/// Training currents (A).
pub const TRAIN_CURRENTS: [f64; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
/// Training tests (the 1 ms sine records): amplitude and frequency as in the file names.
pub const TRAIN_TESTS: [&str; 2] = ["A10mm_f1Hz", "A05mm_f3Hz"];
/// NARX sampling: every this many samples of the 1 ms records.
pub const NARX_DECIMATION: usize = 10;
/// NARX lags (output and input).
pub const NARX_LAGS: usize = 10;
/// NARX neurons.
pub const NARX_NEURONS: usize = 20;
/// NARX seed.
pub const NARX_SEED: u64 = 1;

/// File name of a training record.
pub fn train_file(test: &str, current: f64) -> String {
    format!("sine_{test}_I{current:.2}A.csv")
}

/// The training files in the order they are used (per test, per current).
pub fn train_files() -> Vec<String> {
    TRAIN_TESTS
        .iter()
        .flat_map(|t| TRAIN_CURRENTS.iter().map(move |&i| train_file(t, i)))
        .collect()
}

/// What can go wrong with the MR damper data or its models.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MrDamperError {
    #[error("{dir}: no such folder; give the mr-damper-utfsm data folder with --data-dir")]
    NoFolder { dir: PathBuf },
    #[error("{dir}: the file `{file}` is missing; the folder must hold {EARTHQUAKE_FILE} and the 1 ms sine records sine_A10mm_f1Hz_I<I>A.csv, sine_A05mm_f3Hz_I<I>A.csv for I = 0.00, 0.25, 0.50, 0.75, 1.00 (give it with --data-dir)")]
    MissingFile { dir: PathBuf, file: String },
    #[error("{path}: columns `{found}`, expected exactly `{expected}`")]
    Columns {
        path: PathBuf,
        found: String,
        expected: String,
    },
    #[error("{path} has sampling period {ts} s but {other_path} has {other_ts} s; records of different sampling periods cannot be used together (resample one of them explicitly, or leave it out)")]
    SamplingPeriods {
        path: PathBuf,
        ts: f64,
        other_path: PathBuf,
        other_ts: f64,
    },
    #[error("{path}: {rows} rows; a record needs at least {needed}")]
    TooShort {
        path: PathBuf,
        rows: usize,
        needed: usize,
    },
    #[error("{path}: column I_A is {first} A at row 2 but {value} A at row {row}; a sine record must have one constant current")]
    CurrentNotConstant {
        path: PathBuf,
        first: f64,
        value: f64,
        row: usize,
    },
    #[error("no training record at or around {current} A: the training currents are {have}")]
    NoCurrent { current: f64, have: String },
    #[error("{0}")]
    Data(#[from] DataError),
    #[error("NARX: {0}")]
    Narx(#[from] NarxError),
}

/// One sine record: displacement (mm), force (N), constant current (A).
#[derive(Debug, Clone, PartialEq)]
pub struct DamperRecord {
    pub path: PathBuf,
    /// The test this record belongs to (its file name before `_I`, e.g. `sine_A10mm_f1Hz`):
    /// records of one group are held out together in cross-validation.
    pub group: String,
    pub x: Vec<f64>,
    pub f: Vec<f64>,
    pub current: f64,
    pub ts: f64,
}

/// The earthquake record: displacement and one force column per current.
#[derive(Debug, Clone, PartialEq)]
pub struct EarthquakeRecord {
    pub path: PathBuf,
    pub x: Vec<f64>,
    /// (current in A, force in N), in [`TEST_CURRENTS`] order.
    pub forces: Vec<(f64, Vec<f64>)>,
    pub ts: f64,
}

/// Training and test data.
#[derive(Debug, Clone, PartialEq)]
pub struct MrDamperData {
    pub train: Vec<DamperRecord>,
    pub test: EarthquakeRecord,
}

fn check_columns(rec: &Record, expected: &[&str]) -> Result<(), MrDamperError> {
    if rec
        .names
        .iter()
        .map(String::as_str)
        .ne(expected.iter().copied())
    {
        return Err(MrDamperError::Columns {
            path: rec.path.clone(),
            found: rec.names.join(","),
            expected: expected.join(","),
        });
    }
    Ok(())
}

fn period(rec: &Record) -> Result<f64, MrDamperError> {
    rec.sampling_period()?.ok_or(MrDamperError::TooShort {
        path: rec.path.clone(),
        rows: rec.len(),
        needed: 2,
    })
}

/// Reads a sine record: columns `t_s,x_mm,v_mm_s,F_N,I_A`, uniform time, constant current.
pub fn read_sine(path: &Path) -> Result<DamperRecord, MrDamperError> {
    let rec = read_csv(path)?;
    check_columns(&rec, &SINE_COLUMNS)?;
    let ts = period(&rec)?;
    let i = rec.column("I_A")?;
    if let Some((k, &v)) = i.iter().enumerate().find(|(_, v)| **v != i[0]) {
        return Err(MrDamperError::CurrentNotConstant {
            path: path.to_path_buf(),
            first: i[0],
            value: v,
            row: k + 2,
        });
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    Ok(DamperRecord {
        group: stem.split("_I").next().unwrap_or_default().to_string(),
        path: path.to_path_buf(),
        x: rec.column("x_mm")?.to_vec(),
        f: rec.column("F_N")?.to_vec(),
        current: i[0],
        ts,
    })
}

/// Reads the earthquake record: columns as [`EARTHQUAKE_COLUMNS`], uniform time.
pub fn read_earthquake(path: &Path) -> Result<EarthquakeRecord, MrDamperError> {
    let rec = read_csv(path)?;
    check_columns(&rec, &EARTHQUAKE_COLUMNS)?;
    let ts = period(&rec)?;
    let forces = TEST_CURRENTS
        .iter()
        .zip(&EARTHQUAKE_COLUMNS[2..])
        .map(|(&i, name)| Ok((i, rec.column(name)?.to_vec())))
        .collect::<Result<Vec<_>, DataError>>()?;
    Ok(EarthquakeRecord {
        path: path.to_path_buf(),
        x: rec.column("x_mm")?.to_vec(),
        forces,
        ts,
    })
}

/// All records must share one sampling period; the error names both files and periods.
pub fn check_sampling_periods(records: &[(&Path, f64)]) -> Result<f64, MrDamperError> {
    let Some(&(p0, t0)) = records.first() else {
        return Ok(0.0);
    };
    for &(p, t) in &records[1..] {
        if (t - t0).abs() > 1e-9 * t0 {
            return Err(MrDamperError::SamplingPeriods {
                path: p.to_path_buf(),
                ts: t,
                other_path: p0.to_path_buf(),
                other_ts: t0,
            });
        }
    }
    Ok(t0)
}

/// Reads given training files and a test file (any folder), checking one sampling period.
pub fn load_files(train: &[PathBuf], test: &Path) -> Result<MrDamperData, MrDamperError> {
    let train: Vec<DamperRecord> = train
        .iter()
        .map(|p| read_sine(p))
        .collect::<Result<_, _>>()?;
    let test = read_earthquake(test)?;
    let mut all: Vec<(&Path, f64)> = train.iter().map(|r| (r.path.as_path(), r.ts)).collect();
    all.push((test.path.as_path(), test.ts));
    check_sampling_periods(&all)?;
    Ok(MrDamperData { train, test })
}

/// Reads the data folder: the ten 1 ms sine records and the earthquake record.
pub fn load(dir: &Path) -> Result<MrDamperData, MrDamperError> {
    if !dir.is_dir() {
        return Err(MrDamperError::NoFolder {
            dir: dir.to_path_buf(),
        });
    }
    let mut files = train_files();
    files.push(EARTHQUAKE_FILE.into());
    for f in &files {
        if !dir.join(f).is_file() {
            return Err(MrDamperError::MissingFile {
                dir: dir.to_path_buf(),
                file: f.clone(),
            });
        }
    }
    let train: Vec<PathBuf> = files[..files.len() - 1]
        .iter()
        .map(|f| dir.join(f))
        .collect();
    load_files(&train, &dir.join(EARTHQUAKE_FILE))
}

// ---------------------------------------------------------------------------------------------
// Grey-box

/// The nonlinear force term g of F = c0 dx/dt + k0 x + alpha g + f0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Structure {
    /// g = z, the Bouc-Wen state (n = 1, A = 1) on x: Spencer's simple Bouc-Wen model.
    BoucWen,
    /// g = tanh((dx/dt) / v0): a Bingham plastic (yield force alpha, post-yield damping c0)
    /// smoothed over the velocity v0 (no displacement memory).
    Bingham,
}

impl Structure {
    /// Name in the report.
    pub fn as_str(self) -> &'static str {
        match self {
            Structure::BoucWen => "bouc-wen",
            Structure::Bingham => "bingham",
        }
    }
}

/// Parameters of the grey-box damper model at one current (x in mm, F in N).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SpencerParams {
    pub structure: Structure,
    /// Bingham: the smoothing velocity v0 (mm/s); 0 for Bouc-Wen.
    pub v0: f64,
    /// c0 (N s/mm).
    pub c0: f64,
    /// k0 (N/mm).
    pub k0: f64,
    /// alpha (N/mm): the Bouc-Wen state's weight.
    pub alpha: f64,
    /// Force offset (N).
    pub f0: f64,
    /// Bouc-Wen B (1/mm), A = 1.
    pub b: f64,
    /// Bouc-Wen Gamma (1/mm), |Gamma| <= B.
    pub gamma: f64,
}

/// Rate (mm/s) and Bouc-Wen state z (mm, A = 1) of a displacement from rest.
pub fn states(x: &[f64], ts: f64, b: f64, gamma: f64) -> Option<(Vec<f64>, Vec<f64>)> {
    let spec = BoucWenSpec {
        d: 0.0,
        a: 1.0,
        b,
        gamma,
        n: 1.0,
        initial_h: 0.0,
    };
    let p = spec.check().ok()?;
    // the operator gives y = d u - h = -h
    let z: Vec<f64> = p.operator().apply(x).into_iter().map(|v| -v).collect();
    Some((rate(x, ts), z))
}

/// Rate (mm/s) and the nonlinear term g of a displacement from rest.
pub fn shape_states(
    structure: Structure,
    x: &[f64],
    ts: f64,
    b: f64,
    gamma: f64,
    v0: f64,
) -> Option<(Vec<f64>, Vec<f64>)> {
    match structure {
        Structure::BoucWen => states(x, ts, b, gamma),
        Structure::Bingham => {
            if !(v0.is_finite() && v0 > 0.0) {
                return None;
            }
            let v = rate(x, ts);
            let g = v.iter().map(|w| (w / v0).tanh()).collect();
            Some((v, g))
        }
    }
}

impl SpencerParams {
    /// The force from rest for a displacement `x` (mm) sampled at `ts` (s).
    pub fn simulate(&self, x: &[f64], ts: f64) -> Vec<f64> {
        match shape_states(self.structure, x, ts, self.b, self.gamma, self.v0) {
            Some((v, z)) => (0..x.len())
                .map(|k| self.c0 * v[k] + self.k0 * x[k] + self.alpha * z[k] + self.f0)
                .collect(),
            None => vec![f64::NAN; x.len()],
        }
    }

    /// Linear interpolation between `a` (at `ia`) and `b` (at `ib`) at current `i`.
    pub fn lerp(a: &SpencerParams, ia: f64, b: &SpencerParams, ib: f64, i: f64) -> SpencerParams {
        let w = if ib > ia { (i - ia) / (ib - ia) } else { 0.0 };
        let l = |p: f64, q: f64| p + w * (q - p);
        SpencerParams {
            structure: a.structure,
            v0: l(a.v0, b.v0),
            c0: l(a.c0, b.c0),
            k0: l(a.k0, b.k0),
            alpha: l(a.alpha, b.alpha),
            f0: l(a.f0, b.f0),
            b: l(a.b, b.b),
            gamma: l(a.gamma, b.gamma),
        }
    }
}

/// Linear columns of a record: with `scheduled`, each of (v, x, z, 1) also times I.
fn design_rows(r: &DamperRecord, v: &[f64], z: &[f64], scheduled: bool) -> Vec<[f64; 8]> {
    (0..r.x.len())
        .map(|k| {
            let base = [v[k], r.x[k], z[k], 1.0];
            let i = if scheduled { r.current } else { 0.0 };
            [
                base[0],
                base[1],
                base[2],
                base[3],
                i * base[0],
                i * base[1],
                i * base[2],
                i * base[3],
            ]
        })
        .collect()
}

/// Least squares of F on the columns of every record for fixed (B, Gamma); returns the
/// coefficients and the RMS residual (N). `m` = 4 (one current) or 8 (affine in I).
fn linear_fit(
    recs: &[&DamperRecord],
    structure: Structure,
    (b, gamma, v0): (f64, f64, f64),
    m: usize,
) -> Option<(Vec<f64>, f64)> {
    let mut g = DMatrix::<f64>::zeros(m, m);
    let mut rhs = DVector::<f64>::zeros(m);
    let mut ff = 0.0;
    let mut n = 0usize;
    for r in recs {
        let (v, z) = shape_states(structure, &r.x, r.ts, b, gamma, v0)?;
        for (row, &f) in design_rows(r, &v, &z, m == 8).iter().zip(&r.f) {
            for i in 0..m {
                rhs[i] += row[i] * f;
                for j in 0..m {
                    g[(i, j)] += row[i] * row[j];
                }
            }
            ff += f * f;
            n += 1;
        }
    }
    // column scaling for conditioning
    let d: Vec<f64> = (0..m).map(|i| g[(i, i)].max(1e-300).sqrt()).collect();
    let gs = DMatrix::from_fn(m, m, |i, j| {
        g[(i, j)] / (d[i] * d[j]) + if i == j { 1e-12 } else { 0.0 }
    });
    let bs = DVector::from_fn(m, |i, _| rhs[i] / d[i]);
    let c = gs.cholesky()?.solve(&bs);
    let coef: Vec<f64> = (0..m).map(|i| c[i] / d[i]).collect();
    // residual energy = F'F - 2 c'b + c'Gc
    let mut sse = ff;
    for i in 0..m {
        sse -= 2.0 * coef[i] * rhs[i];
        for j in 0..m {
            sse += coef[i] * g[(i, j)] * coef[j];
        }
    }
    let rms = (sse.max(0.0) / n.max(1) as f64).sqrt();
    rms.is_finite().then_some((coef, rms))
}

/// (B, Gamma) from the search coordinates: B = exp(p) / range, Gamma = B tanh(q).
fn bg(p: &[f64; 2], range: f64) -> (f64, f64) {
    let b = p[0].clamp(-30.0, 30.0).exp() / range;
    (b, b * p[1].clamp(-20.0, 20.0).tanh())
}

/// Nelder-Mead on a 2-D function (deterministic).
fn nelder_mead(f: &dyn Fn(&[f64; 2]) -> f64, x0: [f64; 2], step: f64, iters: usize) -> [f64; 2] {
    let mut s = [x0, [x0[0] + step, x0[1]], [x0[0], x0[1] + step]];
    let mut fs = s.map(|p| f(&p));
    for _ in 0..iters {
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| fs[a].total_cmp(&fs[b]));
        s = idx.map(|i| s[i]);
        fs = idx.map(|i| fs[i]);
        let c = [(s[0][0] + s[1][0]) / 2.0, (s[0][1] + s[1][1]) / 2.0];
        let at = |t: f64| [c[0] + t * (s[2][0] - c[0]), c[1] + t * (s[2][1] - c[1])];
        let xr = at(-1.0);
        let fr = f(&xr);
        if fr < fs[0] {
            let xe = at(-2.0);
            let fe = f(&xe);
            if fe < fr {
                s[2] = xe;
                fs[2] = fe;
            } else {
                s[2] = xr;
                fs[2] = fr;
            }
        } else if fr < fs[1] {
            s[2] = xr;
            fs[2] = fr;
        } else {
            let xc = at(0.5);
            let fc = f(&xc);
            if fc < fs[2] {
                s[2] = xc;
                fs[2] = fc;
            } else {
                for i in 1..3 {
                    s[i] = [(s[0][0] + s[i][0]) / 2.0, (s[0][1] + s[i][1]) / 2.0];
                    fs[i] = f(&s[i]);
                }
            }
        }
        if (fs[2] - fs[0]).abs() <= 1e-10 * fs[0].abs().max(1e-300) {
            break;
        }
    }
    let best = (0..3).min_by(|&a, &b| fs[a].total_cmp(&fs[b])).unwrap_or(0);
    s[best]
}

/// A fit: (B, Gamma) and the linear coefficients, with the training RMS (N).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SpencerFit {
    pub structure: Structure,
    pub v0: f64,
    pub b: f64,
    pub gamma: f64,
    /// c0, k0, alpha, f0 (and, when scheduled, their slopes in I: per A).
    pub coef: Vec<f64>,
    pub train_rms_n: f64,
}

impl SpencerFit {
    /// The parameters at current `i` (A).
    pub fn at(&self, i: f64) -> SpencerParams {
        let c = |k: usize| {
            self.coef[k]
                + if self.coef.len() == 8 {
                    i * self.coef[k + 4]
                } else {
                    0.0
                }
        };
        SpencerParams {
            structure: self.structure,
            v0: self.v0,
            c0: c(0),
            k0: c(1),
            alpha: c(2),
            f0: c(3),
            b: self.b,
            gamma: self.gamma,
        }
    }
}

/// Fits the Spencer (Bouc-Wen) model to records (`scheduled`: coefficients affine in I).
pub fn fit_spencer(recs: &[&DamperRecord], scheduled: bool) -> Option<SpencerFit> {
    fit_structure(recs, Structure::BoucWen, scheduled)
}

/// Golden-section minimisation of `f` on [a, b].
fn golden(f: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        c
    } else {
        d
    }
}

/// Fits a model of the given structure to records: one model (`scheduled`: coefficients
/// affine in I). Variable projection: least squares for (c0, k0, alpha, f0) inside; outside,
/// Bouc-Wen: a grid then Nelder-Mead on (ln B, atanh(Gamma / B)); Bingham: a grid then a
/// golden-section search on ln v0.
pub fn fit_structure(
    recs: &[&DamperRecord],
    structure: Structure,
    scheduled: bool,
) -> Option<SpencerFit> {
    let m = if scheduled { 8 } else { 4 };
    let (b, gamma, v0) = match structure {
        Structure::BoucWen => {
            let range = recs
                .iter()
                .flat_map(|r| r.x.iter())
                .fold(0.0f64, |a, v| a.max(v.abs()))
                .max(1e-12);
            let cost = |p: &[f64; 2]| {
                let (b, g) = bg(p, range);
                linear_fit(recs, structure, (b, g, 0.0), m).map_or(f64::INFINITY, |(_, r)| r)
            };
            let grid: Vec<[f64; 2]> = [1.0f64, 3.0, 10.0, 30.0, 100.0, 300.0]
                .iter()
                .flat_map(|&br| [-0.5f64, 0.0, 0.5].map(|q| [br.ln(), q]))
                .collect();
            let costs: Vec<f64> = grid.par_iter().map(&cost).collect();
            let best = (0..grid.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
            let p = nelder_mead(&cost, grid[best], 0.3, 200);
            let (b, g) = bg(&p, range);
            (b, g, 0.0)
        }
        Structure::Bingham => {
            let cost = |lv: f64| {
                linear_fit(recs, structure, (0.0, 0.0, lv.exp()), m)
                    .map_or(f64::INFINITY, |(_, r)| r)
            };
            let grid: Vec<f64> = [0.5f64, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]
                .iter()
                .map(|v| v.ln())
                .collect();
            let costs: Vec<f64> = grid.par_iter().map(|&p| cost(p)).collect();
            let best = (0..grid.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
            let lv = golden(&cost, grid[best] - 0.8, grid[best] + 0.8, 40);
            (0.0, 0.0, lv.exp())
        }
    };
    let (coef, train_rms_n) = linear_fit(recs, structure, (b, gamma, v0), m)?;
    Some(SpencerFit {
        structure,
        v0,
        b,
        gamma,
        coef,
        train_rms_n,
    })
}

/// One Spencer model per training current.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PerCurrent {
    /// (current, fit), by increasing current.
    pub fits: Vec<(f64, SpencerFit)>,
}

impl PerCurrent {
    /// Every parameter interpolated linearly between the neighbouring training currents
    /// (held at the end values outside them).
    pub fn at(&self, i: f64) -> SpencerParams {
        let f = &self.fits;
        let k = f.iter().position(|(c, _)| *c >= i).unwrap_or(f.len() - 1);
        if k == 0 || (f[k].0 - i).abs() < 1e-12 || f[k].0 < i {
            return f[k].1.at(i);
        }
        SpencerParams::lerp(&f[k - 1].1.at(i), f[k - 1].0, &f[k].1.at(i), f[k].0, i)
    }
}

/// Fits one model per distinct training current.
pub fn fit_per_current(
    recs: &[DamperRecord],
    structure: Structure,
) -> Result<PerCurrent, MrDamperError> {
    let mut currents: Vec<f64> = recs.iter().map(|r| r.current).collect();
    currents.sort_by(f64::total_cmp);
    currents.dedup();
    let fits: Vec<Option<SpencerFit>> = currents
        .par_iter()
        .map(|&i| {
            let mine: Vec<&DamperRecord> = recs.iter().filter(|r| r.current == i).collect();
            fit_structure(&mine, structure, false)
        })
        .collect();
    let mut out = Vec::new();
    for (i, f) in currents.into_iter().zip(fits) {
        out.push((
            i,
            f.ok_or(MrDamperError::NoCurrent {
                current: i,
                have: "(the fit at this current failed: non-finite least squares)".into(),
            })?,
        ));
    }
    if out.is_empty() {
        return Err(MrDamperError::NoCurrent {
            current: f64::NAN,
            have: "none".into(),
        });
    }
    Ok(PerCurrent { fits: out })
}

// ---------------------------------------------------------------------------------------------
// NARX

/// Every `m`-th sample.
pub fn decimate(x: &[f64], m: usize) -> Vec<f64> {
    x.iter().step_by(m.max(1)).copied().collect()
}

/// The NARX record of a displacement at constant current (decimated), with or without force.
pub fn narx_record(name: &Path, x: &[f64], current: f64, f: Option<&[f64]>, ts: f64) -> IoRecord {
    let xd = decimate(x, NARX_DECIMATION);
    let n = xd.len();
    IoRecord {
        path: name.to_path_buf(),
        ts: ts * NARX_DECIMATION as f64,
        t0: 0.0,
        time_name: "t_s".into(),
        inputs: vec![
            Signal {
                name: "x_mm".into(),
                values: xd,
            },
            Signal {
                name: "I_A".into(),
                values: vec![current; n],
            },
        ],
        outputs: f
            .map(|f| {
                vec![Signal {
                    name: "F_N".into(),
                    values: decimate(f, NARX_DECIMATION),
                }]
            })
            .unwrap_or_default(),
    }
}

/// The NARX configuration: default protocol, inputs x and I, [`NARX_LAGS`] lags,
/// [`NARX_NEURONS`] neurons, 2 restarts, 600 simulation-error steps in all, seed 1.
pub fn narx_config() -> NarxConfig {
    let mut c = NarxConfig::new(vec!["x_mm".into(), "I_A".into()], vec!["F_N".into()]);
    c.seed = NARX_SEED;
    c.lags = Lags {
        output: NARX_LAGS,
        input: NARX_LAGS,
        delay: 1,
    };
    c.neurons = NARX_NEURONS;
    // the current scales the damper's force (a product of the inputs' effects): not additive
    c.interaction = Interaction::Full;
    c.robust.restarts = Some(2);
    c.robust.sim_steps = 600;
    c
}

/// Trains the NARX on the (decimated) training records.
pub fn fit_narx(data: &MrDamperData) -> Result<FittedNarx, MrDamperError> {
    let recs: Vec<IoRecord> = data
        .train
        .iter()
        .map(|r| narx_record(&r.path, &r.x, r.current, Some(&r.f), r.ts))
        .collect();
    Ok(narx_config().fit_records(&recs)?)
}

// ---------------------------------------------------------------------------------------------
// Scoring and the whole study

/// The score of one model at one test current; `None` = the free run diverged.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CurrentScore {
    pub current: f64,
    pub r2: Option<f64>,
    pub rms_n: Option<f64>,
}

/// Scores a prediction (`None` or non-finite = diverged).
pub fn score(current: f64, measured: &[f64], predicted: Option<&[f64]>) -> CurrentScore {
    match predicted {
        Some(p) if p.len() == measured.len() && p.iter().all(|v| v.is_finite()) => {
            let s = metrics::scores(measured, p);
            CurrentScore {
                current,
                r2: s.r2,
                rms_n: Some(s.rmse),
            }
        }
        _ => CurrentScore {
            current,
            r2: None,
            rms_n: None,
        },
    }
}

/// One grey-box variant: a structure, scheduled (one model, affine in I) or per current
/// (interpolated), its fit and its test scores and predictions.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyBoxVariant {
    pub structure: Structure,
    pub scheduled: bool,
    /// Scheduled: the one fit; per current: empty (see `per_current`).
    pub fit: Option<SpencerFit>,
    pub per_current: Option<PerCurrent>,
    /// Leave-one-test-out RMS (N) on the training records (scheduled variants only).
    pub cv_rms_n: Option<f64>,
    pub scores: Vec<CurrentScore>,
    /// Free run on the test record per current (1 ms).
    pub predictions: Vec<Vec<f64>>,
}

impl GreyBoxVariant {
    /// `bouc-wen scheduled`, `bingham per-current`…
    pub fn name(&self) -> String {
        format!(
            "{} {}",
            self.structure.as_str(),
            if self.scheduled {
                "scheduled"
            } else {
                "per-current"
            }
        )
    }

    /// The parameters at current `i`.
    pub fn at(&self, i: f64) -> Option<SpencerParams> {
        match (&self.fit, &self.per_current) {
            (Some(f), _) => Some(f.at(i)),
            (None, Some(p)) => Some(p.at(i)),
            _ => None,
        }
    }
}

/// Everything the study measures.
#[derive(Debug, Clone, PartialEq)]
pub struct MrDamperResult {
    pub narx: Vec<CurrentScore>,
    /// NARX free runs (10 ms; `None` when diverged).
    pub narx_predictions: Vec<Option<Vec<f64>>>,
    /// Every grey-box variant; `greybox[headline]` is the one chosen by cross-validation on
    /// the training records (lowest `cv_rms_n` among the scheduled variants).
    pub greybox: Vec<GreyBoxVariant>,
    pub headline: usize,
    pub narx_seconds: f64,
    pub greybox_seconds: f64,
    pub train_samples: usize,
    pub test_samples: usize,
}

/// Leave-one-test-out cross-validation of a scheduled structure on the training records:
/// for each test group (e.g. all 1 Hz records), fit on the others and run the held-out
/// records from rest; the pooled RMS error (N). `None` with fewer than two groups.
pub fn cross_validate(recs: &[DamperRecord], structure: Structure) -> Option<f64> {
    let mut groups: Vec<&str> = recs.iter().map(|r| r.group.as_str()).collect();
    groups.sort_unstable();
    groups.dedup();
    if groups.len() < 2 {
        return None;
    }
    let parts: Vec<Option<(f64, usize)>> = groups
        .par_iter()
        .map(|g| {
            let train: Vec<&DamperRecord> = recs.iter().filter(|r| r.group != *g).collect();
            let fit = fit_structure(&train, structure, true)?;
            let mut sse = 0.0;
            let mut n = 0;
            for r in recs.iter().filter(|r| r.group == *g) {
                let p = fit.at(r.current).simulate(&r.x, r.ts);
                sse += p
                    .iter()
                    .zip(&r.f)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>();
                n += r.f.len();
            }
            Some((sse, n))
        })
        .collect();
    let (mut sse, mut n) = (0.0, 0usize);
    for p in parts {
        let (s, k) = p?;
        sse += s;
        n += k;
    }
    let rms = (sse / n.max(1) as f64).sqrt();
    rms.is_finite().then_some(rms)
}

fn failed(what: &str) -> MrDamperError {
    MrDamperError::NoCurrent {
        current: f64::NAN,
        have: format!("(the {what} fit failed: non-finite least squares)"),
    }
}

/// The grey-box part: every structure, scheduled and per current, scored on the test record;
/// the headline is the scheduled structure with the lowest cross-validation error on the
/// training records (the test record plays no part in the choice).
pub fn run_greybox(data: &MrDamperData) -> Result<(Vec<GreyBoxVariant>, usize), MrDamperError> {
    let all: Vec<&DamperRecord> = data.train.iter().collect();
    let t = &data.test;
    let mut out = Vec::new();
    for structure in [Structure::BoucWen, Structure::Bingham] {
        let fit = fit_structure(&all, structure, true).ok_or_else(|| failed("scheduled"))?;
        let cv = cross_validate(&data.train, structure);
        let per = fit_per_current(&data.train, structure)?;
        for (scheduled, fit, per) in [(true, Some(fit), None), (false, None, Some(per))] {
            let mut v = GreyBoxVariant {
                structure,
                scheduled,
                fit,
                per_current: per,
                cv_rms_n: if scheduled { cv } else { None },
                scores: Vec::new(),
                predictions: Vec::new(),
            };
            for (i, f) in &t.forces {
                let p = v
                    .at(*i)
                    .ok_or_else(|| failed("grey-box"))?
                    .simulate(&t.x, t.ts);
                v.scores.push(score(*i, f, Some(&p)));
                v.predictions.push(p);
            }
            out.push(v);
        }
    }
    let headline = (0..out.len())
        .filter(|&k| out[k].scheduled)
        .min_by(|&a, &b| {
            let c = |k: usize| out[k].cv_rms_n.unwrap_or(f64::INFINITY);
            c(a).total_cmp(&c(b))
        })
        .unwrap_or(0);
    Ok((out, headline))
}

/// NARX free runs per current (`None` when diverged).
pub type NarxPredictions = Vec<Option<Vec<f64>>>;

/// The NARX part: free run per current on the decimated test record.
pub fn score_narx(
    model: &FittedNarx,
    data: &MrDamperData,
) -> Result<(Vec<CurrentScore>, NarxPredictions), MrDamperError> {
    let t = &data.test;
    let mut scores = Vec::new();
    let mut preds = Vec::new();
    for (i, f) in &t.forces {
        let rec = narx_record(&t.path, &t.x, *i, None, t.ts);
        let p = model.predict(&rec, Mode::FreeRun)?;
        let p = &p[0];
        let measured = decimate(f, NARX_DECIMATION);
        let pred = p.diverged_at.is_none().then(|| p.values.clone());
        scores.push(score(*i, &measured, pred.as_deref()));
        preds.push(pred);
    }
    Ok((scores, preds))
}

/// The whole study: NARX and grey-box trained on the sine records, scored on the earthquake
/// record per current.
pub fn run(data: &MrDamperData) -> Result<MrDamperResult, MrDamperError> {
    let t = std::time::Instant::now();
    let (greybox, headline) = run_greybox(data)?;
    let greybox_seconds = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let model = fit_narx(data)?;
    let narx_seconds = t.elapsed().as_secs_f64();
    let (narx, narx_predictions) = score_narx(&model, data)?;
    Ok(MrDamperResult {
        narx,
        narx_predictions,
        greybox,
        headline,
        narx_seconds,
        greybox_seconds,
        train_samples: data.train.iter().map(|r| r.x.len()).sum(),
        test_samples: data.test.x.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(i: f64, n: usize, ts: f64, p: &SpencerParams) -> DamperRecord {
        let x: Vec<f64> = (0..n)
            .map(|k| 5.0 * (2.0 * std::f64::consts::PI * 2.0 * k as f64 * ts).sin())
            .collect();
        let f = p.simulate(&x, ts);
        DamperRecord {
            path: PathBuf::from(format!("sim{i}")),
            group: format!("g{}", n % 2),
            x,
            f,
            current: i,
            ts,
        }
    }

    #[test]
    fn spencer_fit_recovers_a_simulated_damper() {
        let truth = |i: f64| SpencerParams {
            structure: Structure::BoucWen,
            v0: 0.0,
            c0: 1.0 + 2.0 * i,
            k0: 3.0,
            alpha: 50.0 + 100.0 * i,
            f0: 0.0,
            b: 2.0,
            gamma: 0.5,
        };
        let recs: Vec<DamperRecord> = [0.0, 0.5, 1.0]
            .iter()
            .map(|&i| sine(i, 2000, 1e-3, &truth(i)))
            .collect();
        let refs: Vec<&DamperRecord> = recs.iter().collect();
        let fit = fit_spencer(&refs, true).unwrap();
        assert!(fit.train_rms_n < 1e-4, "{fit:?}");
        let p = fit.at(0.25);
        let t = truth(0.25);
        assert!(
            (p.b - t.b).abs() < 1e-3 && (p.gamma - t.gamma).abs() < 1e-3,
            "{p:?}"
        );
        assert!(
            (p.c0 - t.c0).abs() < 1e-3 && (p.alpha - t.alpha).abs() < 1e-2,
            "{p:?}"
        );
        let per = fit_per_current(&recs, Structure::BoucWen).unwrap();
        let q = per.at(0.25);
        assert!((q.c0 - t.c0).abs() < 1e-3, "{q:?}");
    }

    #[test]
    fn mixed_sampling_periods_are_refused_naming_both() {
        let e = check_sampling_periods(&[
            (Path::new("a.csv"), 0.001),
            (Path::new("b.csv"), 0.001),
            (Path::new("c.csv"), 0.005),
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("c.csv")
                && e.contains("0.005")
                && e.contains("a.csv")
                && e.contains("0.001"),
            "{e}"
        );
    }

    #[test]
    fn diverged_is_not_a_number() {
        let s = score(0.2, &[1.0, 2.0], None);
        assert_eq!((s.r2, s.rms_n), (None, None));
        let s = score(0.2, &[1.0, 2.0], Some(&[1.0, f64::INFINITY]));
        assert_eq!(s.rms_n, None);
        let s = score(0.2, &[1.0, 2.0, 3.0], Some(&[1.0, 2.0, 4.0]));
        assert!((s.rms_n.unwrap() - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
    }
}
