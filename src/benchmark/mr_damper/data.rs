//! The MR damper study's records: the file names, the readers and their errors.

use super::*;

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
/// The other sine tests (5 ms records: 25 mm at 0.1, 0.25, 0.5 Hz and 2 mm at 5 Hz): the
/// grey-box models, which run at each record's own sampling period, train on them too when
/// they are in the folder; the NARX, whose lags are counted in samples, does not.
pub const OTHER_TESTS: [&str; 4] = [
    "A25mm_f0.1Hz",
    "A25mm_f0.25Hz",
    "A25mm_f0.5Hz",
    "A02mm_f5Hz",
];
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
    /// The ten 1 ms sine records (every model trains on them).
    pub train: Vec<DamperRecord>,
    /// The sine records of [`OTHER_TESTS`] found in the folder (the grey-box models only).
    pub other: Vec<DamperRecord>,
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
    Ok(MrDamperData {
        train,
        other: Vec::new(),
        test,
    })
}

/// Reads the data folder: the ten 1 ms sine records, the earthquake record, and the sine
/// records of [`OTHER_TESTS`] that are there.
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
    let mut data = load_files(&train, &dir.join(EARTHQUAKE_FILE))?;
    for t in OTHER_TESTS {
        for i in TRAIN_CURRENTS {
            let p = dir.join(train_file(t, i));
            if p.is_file() {
                data.other.push(read_sine(&p)?);
            }
        }
    }
    Ok(data)
}
