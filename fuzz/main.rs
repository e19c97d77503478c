//! A mutation fuzzer for the files users hand to hystbench: records (CSV), plant files,
//! scenario files and model files. It needs no nightly toolchain: seeds (the shipped files,
//! lab-style CSVs, freshly fitted models, and every input found before) are mutated byte by
//! byte and, when they are JSON, node by node (numbers set to the values that break code:
//! 0, -1, 1e308, 2^64...; types swapped; keys dropped; arrays emptied or grown), and each
//! mutant runs through the target (`fuzz/targets.rs`) under `catch_unwind` and a time limit.
//!
//! Run: `cargo run --release --example fuzz -- TARGET [--seconds S] [--seed N] [--timeout S]`
//! with TARGET one of `csv`, `plant`, `scenario`, `model`. An input that panics, hangs or
//! aborts (an allocation failure) is written to `fuzz/found/TARGET/`; `tests/fuzz_found.rs`
//! replays every such file, so a fix stays fixed. Exit status 1 when something was found.

#[path = "targets.rs"]
mod targets;

use rand::rngs::Xoshiro256PlusPlus;
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

struct Options {
    target: String,
    seconds: f64,
    seed: u64,
    timeout: f64,
}

fn options() -> Result<Options, String> {
    let mut args = std::env::args().skip(1);
    let mut o = Options {
        target: String::new(),
        seconds: 60.0,
        seed: 1,
        timeout: 10.0,
    };
    while let Some(a) = args.next() {
        let mut value = |name: &str| -> Result<f64, String> {
            args.next()
                .and_then(|v| v.parse().ok())
                .ok_or(format!("{name} needs a number"))
        };
        match a.as_str() {
            "--seconds" => o.seconds = value("--seconds")?,
            "--seed" => o.seed = value("--seed")? as u64,
            "--timeout" => o.timeout = value("--timeout")?,
            t if !t.starts_with('-') && o.target.is_empty() => o.target = t.to_string(),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    if !targets::TARGETS.contains(&o.target.as_str()) {
        return Err(format!(
            "name a target: one of {}",
            targets::TARGETS.join(", ")
        ));
    }
    Ok(o)
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn files(dir: &Path, ext: &str) -> Vec<Vec<u8>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    paths.sort();
    paths
        .into_iter()
        .filter(|p| ext.is_empty() || p.extension().is_some_and(|e| e == ext))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| !n.to_string_lossy().starts_with('.'))
        })
        .filter_map(|p| std::fs::read(p).ok())
        .collect()
}

/// A short record of the Bouc-Wen plant (for the model seeds).
fn small_record() -> hystbench::data::IoRecord {
    hystbench::narx::synthetic::seed_1dof(hystbench::narx::synthetic::Plant1::BoucWen, 1_500, 3)
}

fn seeds(target: &str) -> Vec<Vec<u8>> {
    let r = root();
    let mut out = match target {
        "csv" => {
            // the first 300 lines of each (a mutant of a 10 MB file costs what 10,000 small ones do)
            let mut v: Vec<Vec<u8>> = files(&r.join("tests/data"), "csv")
                .into_iter()
                .map(|f| {
                    let end = f
                        .iter()
                        .enumerate()
                        .filter(|(_, &b)| b == b'\n')
                        .nth(299)
                        .map_or(f.len(), |(i, _)| i + 1);
                    f[..end].to_vec()
                })
                .collect();
            v.push(b"t,u,y\n0,0,0\n0.001,1,0.5\n0.002,2,1.5\n0.003,1,1.2\n0.004,0,0.1\n".to_vec());
            v.push(b"# logged 2026-11-01\n# rig 3\ntime [s];voltage (V);displacement [um];\n0,0;0,0;0,01;\n0,001;1,5;0,7;\n0,002;3,0;1,9;\n0,003;1,5;1,1;\n".to_vec());
            v.push(b"\"t\"\t\"u1\"\t\"u2\"\t\"y1\"\t\"y2\"\n0\t0\t0\t0\t0\n1e-3\t1\t-1\t0.5\t-0.4\n2e-3\t2\t-2\t1.1\t-0.9\n".to_vec());
            v
        }
        "plant" => files(&r.join("plants"), "json"),
        "scenario" => files(&r.join("scenarios"), "json"),
        "model" => {
            let mut v = files(&r.join("plants"), "json");
            let rec = small_record();
            for effects in ["hysteresis", "bouc-wen,dynamics", "hysteresis,creep"] {
                if let Ok(m) = hystbench::graybox::GreyBoxConfig::from_effect_list(effects)
                    .and_then(|c| c.fit(&rec))
                {
                    if let Ok(text) = m.to_json() {
                        v.push(text.into_bytes());
                    }
                }
            }
            let mut c = hystbench::narx::NarxConfig::new(rec.input_names(), rec.output_names());
            c.epochs = 3;
            if let Ok(m) = c.fit(&rec) {
                v.push(m.to_json().into_bytes());
            }
            v
        }
        _ => Vec::new(),
    };
    out.extend(files(&r.join("fuzz/found").join(target), ""));
    out
}

/// Numbers that break code.
const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "3",
    "0.5",
    "1e-300",
    "-1e-300",
    "5e-324",
    "1e300",
    "-1e300",
    "1.7976931348623157e308",
    "1e309",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "-9223372036854775808",
    "1e9",
    "1e20",
    "100000000",
    "65536",
];
/// Bytes and words that mean something to the readers.
const TOKENS: &[&str] = &[
    ",", ";", "\t", "\n", "\r\n", "#", "\"", ".", "-", "e", "E", "NaN", "inf", "-inf", "nan", "[",
    "]", "{", "}", ":", "null", "true", "\"\"", " ", "\u{feff}", "[um]", "(V)", ",,", "1,5",
    "\\u0000", "\u{0}", "é",
];

struct Mutator {
    rng: Xoshiro256PlusPlus,
}

impl Mutator {
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.rng.next_u64() % n as u64) as usize
        }
    }

    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }

    fn bytes(&mut self, data: &mut Vec<u8>, other: &[u8]) {
        let n = data.len();
        match self.below(8) {
            0 if n > 0 => {
                let i = self.below(n);
                data[i] ^= 1 << self.below(8);
            }
            1 if n > 0 => {
                let i = self.below(n);
                data[i] = self.rng.next_u32() as u8;
            }
            2 => {
                let i = self.below(n + 1);
                let t = self.pick(TOKENS).as_bytes().to_vec();
                data.splice(i..i, t);
            }
            3 if n > 0 => {
                let i = self.below(n);
                let len = 1 + self.below((n - i).min(64));
                data.drain(i..i + len);
            }
            4 if n > 0 => {
                let i = self.below(n);
                let len = 1 + self.below((n - i).min(256));
                let chunk = data[i..i + len].to_vec();
                let at = self.below(n + 1);
                data.splice(at..at, chunk);
            }
            5 if n > 0 => data.truncate(self.below(n)),
            6 if !other.is_empty() => {
                let (a, b) = (self.below(n + 1), self.below(other.len()));
                data.truncate(a);
                data.extend_from_slice(&other[b..]);
            }
            _ => {
                // a number in the text replaced by one that breaks code
                let text = String::from_utf8_lossy(data).to_string();
                let spans: Vec<(usize, usize)> = number_spans(&text);
                if let Some(&(a, b)) = (!spans.is_empty()).then(|| self.pick(&spans)) {
                    let num = self.pick(NUMBERS).to_string();
                    *data = format!("{}{num}{}", &text[..a], &text[b..]).into_bytes();
                }
            }
        }
    }

    fn json(&mut self, v: &mut serde_json::Value, donor: &serde_json::Value) {
        use serde_json::Value;
        let mut nodes = Vec::new();
        collect(v, &mut Vec::new(), &mut nodes);
        let path = self.pick(&nodes).clone();
        let node = at(v, &path);
        match self.below(7) {
            0 => {
                let n = self.pick(NUMBERS);
                *node = serde_json::from_str(n).unwrap_or(Value::Null);
            }
            1 => {
                *node = match self.below(5) {
                    0 => Value::Null,
                    1 => Value::String(self.pick(TOKENS).to_string()),
                    2 => Value::Array(Vec::new()),
                    3 => Value::Object(Default::default()),
                    _ => Value::Bool(true),
                }
            }
            2 => match node {
                Value::Object(m) if !m.is_empty() => {
                    let k = m
                        .keys()
                        .nth(self.below(m.len()))
                        .cloned()
                        .unwrap_or_default();
                    m.remove(&k);
                }
                Value::Array(a) if !a.is_empty() => {
                    let i = self.below(a.len());
                    a.remove(i);
                }
                _ => {}
            },
            3 => {
                if let Value::Array(a) = node {
                    if !a.is_empty() {
                        let i = self.below(a.len());
                        let copy = a[i].clone();
                        for _ in 0..1 + self.below(4) {
                            a.push(copy.clone());
                        }
                    }
                }
            }
            4 => {
                // a subtree of the donor (another seed) put here
                let mut dn = Vec::new();
                collect(donor, &mut Vec::new(), &mut dn);
                let p = self.pick(&dn).clone();
                let mut d = donor.clone();
                *node = at(&mut d, &p).clone();
            }
            5 => {
                if let Value::Number(n) = node {
                    let x = n.as_f64().unwrap_or(0.0);
                    let f = [-1.0, 0.0, 0.5, 2.0, 10.0, 1e6, -1e-9][self.below(7)];
                    *node = serde_json::Number::from_f64(x * f)
                        .map(Value::Number)
                        .unwrap_or(Value::Null);
                }
            }
            _ => {
                if let Value::Object(m) = node {
                    m.insert(self.pick(TOKENS).to_string(), Value::Null);
                }
            }
        }
    }
}

/// Byte spans of the numbers in a text.
fn number_spans(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut k = 0;
    while k < b.len() {
        if b[k].is_ascii_digit() {
            let a = k;
            while k < b.len() && (b[k].is_ascii_digit() || b"eE.+-".contains(&b[k])) {
                k += 1;
            }
            out.push((a, k));
        } else {
            k += 1;
        }
    }
    out
}

/// A step down a JSON document.
#[derive(Clone)]
enum Step {
    Key(String),
    Index(usize),
}

type NodePath = Vec<Step>;

fn collect(v: &serde_json::Value, path: &mut NodePath, out: &mut Vec<NodePath>) {
    out.push(path.clone());
    match v {
        serde_json::Value::Object(m) => {
            for (k, c) in m {
                path.push(Step::Key(k.clone()));
                collect(c, path, out);
                path.pop();
            }
        }
        serde_json::Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                path.push(Step::Index(i));
                collect(c, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(v: &'a mut serde_json::Value, path: &NodePath) -> &'a mut serde_json::Value {
    let mut node = v;
    for s in path {
        node = match s {
            Step::Key(k) => node.get_mut(k.as_str()).expect("a collected key"),
            Step::Index(i) => node.get_mut(*i).expect("a collected index"),
        };
    }
    node
}

fn hash(data: &[u8]) -> u64 {
    // FNV-1a: a stable name for an input
    data.iter().fold(0xcbf29ce484222325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

fn main() {
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}\nusage: cargo run --release --example fuzz -- TARGET [--seconds S] [--seed N] [--timeout S]");
            std::process::exit(2);
        }
    };
    let found = root().join("fuzz/found").join(&o.target);
    std::fs::create_dir_all(&found).expect("create fuzz/found");
    // the input that runs, kept in memory-backed storage where there is one (a write per run)
    let shm = Path::new("/dev/shm");
    let current = if shm.is_dir() {
        shm.join(format!("hystbench-fuzz-{}.current", o.target))
    } else {
        found.join(".current")
    };
    // an input left by a run that died (an allocation failure cannot be caught)
    if let Ok(input) = std::fs::read(&current) {
        let p = found.join(format!("abort-{:016x}", hash(&input)));
        let _ = std::fs::rename(&current, &p);
        eprintln!("abort: the last run died on {}", p.display());
    }
    let seeds = seeds(&o.target);
    assert!(!seeds.is_empty(), "no seeds for {}", o.target);
    let json_seeds: Vec<Option<serde_json::Value>> = seeds
        .iter()
        .map(|s| serde_json::from_slice(s).ok())
        .collect();
    // the panic's place, kept by the hook (the default hook would print every one)
    let last_panic: Arc<Mutex<String>> = Arc::default();
    {
        let lp = last_panic.clone();
        std::panic::set_hook(Box::new(move |info| {
            let place = info
                .location()
                .map(|l| format!("{}:{}", l.file(), l.line()))
                .unwrap_or_default();
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            *lp.lock().unwrap() = format!("{place}: {msg}");
        }));
    }
    // the worker runs the target; the main thread keeps time
    let (to_worker, work) = mpsc::channel::<Vec<u8>>();
    let (done, from_worker) = mpsc::channel::<Result<(), ()>>();
    let target = o.target.clone();
    std::thread::spawn(move || {
        for input in work {
            let r = std::panic::catch_unwind(|| targets::run(&target, &input)).map_err(|_| ());
            if done.send(r).is_err() {
                break;
            }
        }
    });
    let mut m = Mutator {
        rng: Xoshiro256PlusPlus::seed_from_u64(o.seed),
    };
    let start = Instant::now();
    let (mut execs, mut panics) = (0u64, BTreeMap::<String, (u64, PathBuf)>::new());
    let mut slowest = 0.0f64;
    let mut k = 0usize;
    while start.elapsed().as_secs_f64() < o.seconds {
        // the seeds as they are first, then mutants of 1 to 4 stacked mutations
        let input = if k < seeds.len() {
            seeds[k].clone()
        } else {
            let i = m.below(seeds.len());
            let donor = m.below(seeds.len());
            let mut data = seeds[i].clone();
            for _ in 0..1 + m.below(4) {
                match (&json_seeds[i], &json_seeds[donor], m.below(3)) {
                    (Some(_), Some(d), 0 | 1) => {
                        if let Ok(mut v) = serde_json::from_slice::<serde_json::Value>(&data) {
                            m.json(&mut v, d);
                            data = serde_json::to_vec_pretty(&v).unwrap_or(data);
                        } else {
                            m.bytes(&mut data, &seeds[donor]);
                        }
                    }
                    _ => m.bytes(&mut data, &seeds[donor]),
                }
            }
            data
        };
        k += 1;
        // kept while it runs: an abort (allocation failure, the OOM killer) leaves it behind
        let _ = std::fs::write(&current, &input);
        let t0 = Instant::now();
        to_worker.send(input.clone()).expect("the worker runs");
        match from_worker.recv_timeout(Duration::from_secs_f64(o.timeout)) {
            Ok(Ok(())) => {}
            Ok(Err(())) => {
                let place = last_panic.lock().unwrap().clone();
                let key = place.split(": ").next().unwrap_or_default().to_string();
                let entry = panics.entry(key).or_insert_with(|| {
                    let p = found.join(format!("panic-{:016x}", hash(&input)));
                    let _ = std::fs::write(&p, &input);
                    eprintln!("panic: {place}\n  input: {}", p.display());
                    (0, p)
                });
                entry.0 += 1;
            }
            Err(_) => {
                let p = found.join(format!("hang-{:016x}", hash(&input)));
                let _ = std::fs::write(&p, &input);
                let _ = std::fs::remove_file(&current);
                eprintln!(
                    "hang: no answer within {} s\n  input: {}",
                    o.timeout,
                    p.display()
                );
                std::process::exit(1);
            }
        }
        slowest = slowest.max(t0.elapsed().as_secs_f64());
        execs += 1;
    }
    let _ = std::fs::remove_file(&current);
    let secs = start.elapsed().as_secs_f64();
    println!(
        "fuzz {}: {execs} executions in {secs:.0} s ({:.0}/s), seed {}, {} seeds; slowest input {slowest:.3} s; {} panic place(s)",
        o.target,
        execs as f64 / secs,
        o.seed,
        seeds.len(),
        panics.len()
    );
    for (place, (count, p)) in &panics {
        println!("  {count} x {place} (first input: {})", p.display());
    }
    if !panics.is_empty() {
        std::process::exit(1);
    }
}
