//! An experiment's output directory: `run.json` (settings, version, commit, wall time),
//! `cells.jsonl` (one line per finished cell, appended and synced as it completes, so that a
//! killed run loses at most the cells in progress) and the result files.

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use graybox::error::{Error, Result};
use graybox::model::file::write_atomic;

const CELLS: &str = "cells.jsonl";
const RUN: &str = "run.json";

/// What `run.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct RunInfo {
    experiment: String,
    settings: Value,
    graybox_version: String,
    commit: String,
    command: Vec<String>,
    started: String,
    updated: String,
    /// Summed over every invocation that worked on this directory.
    wall_seconds: f64,
    invocations: u32,
    complete: bool,
}

/// One line of `cells.jsonl`.
#[derive(Serialize, Deserialize)]
struct CellLine {
    key: String,
    value: Value,
}

pub struct OutDir {
    dir: PathBuf,
    log: Mutex<File>,
    cells: Mutex<BTreeMap<String, Value>>,
    run: RunInfo,
    started: Instant,
}

/// The environment variable naming a cell after whose record the process dies, as a kill at
/// that instant would (the tests' way to stop a run at its least convenient point).
const KILL_AFTER: &str = "GRAYBOX_LAB_KILL_AFTER";

/// Ends the process at once, without unwinding or flushing, when `KILL_AFTER` names `key`.
pub fn killed_after(key: &str) {
    if std::env::var(KILL_AFTER).is_ok_and(|k| k == key) {
        eprintln!("{KILL_AFTER}={key}: stopping here");
        std::process::abort();
    }
}

fn io(path: &Path, e: std::io::Error) -> Error {
    Error::Io(std::io::Error::new(
        e.kind(),
        format!("{}: {e}", path.display()),
    ))
}

fn now() -> String {
    chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

impl OutDir {
    /// Opens `dir` for `experiment` with `settings`: a new directory starts a run; one holding
    /// a run of the same experiment and settings continues it; anything else is an error that
    /// names the difference (results of different settings must not mix).
    pub fn open(dir: &Path, experiment: &str, settings: &impl Serialize) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        let settings = serde_json::to_value(settings).expect("settings serialize");
        let run_path = dir.join(RUN);
        let previous: Option<RunInfo> = match std::fs::read(&run_path) {
            Ok(bytes) => {
                Some(serde_json::from_slice(&bytes).map_err(|e| Error::corrupt("run.json", e))?)
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(io(&run_path, e)),
        };
        if let Some(p) = &previous {
            check_same(dir, p, experiment, &settings)?;
        }
        let cells_path = dir.join(CELLS);
        let cells = read_cells(&cells_path)?;
        let log = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&cells_path)
            .map_err(|e| io(&cells_path, e))?;
        let run = RunInfo {
            experiment: experiment.to_string(),
            settings,
            graybox_version: env!("CARGO_PKG_VERSION").to_string(),
            commit: env!("GRAYBOX_COMMIT").to_string(),
            command: std::env::args().collect(),
            started: previous.as_ref().map_or_else(now, |p| p.started.clone()),
            updated: now(),
            wall_seconds: previous.as_ref().map_or(0.0, |p| p.wall_seconds),
            invocations: previous.as_ref().map_or(0, |p| p.invocations) + 1,
            complete: false,
        };
        let out = Self {
            dir: dir.to_path_buf(),
            log: Mutex::new(log),
            cells: Mutex::new(cells),
            run,
            started: Instant::now(),
        };
        out.write_run(false)?;
        Ok(out)
    }

    /// A finished cell's value, if it is there and of this type.
    pub fn get<T: DeserializeOwned>(&self, key: &str) -> Option<T> {
        let cells = self.cells.lock().expect("cells lock");
        serde_json::from_value(cells.get(key)?.clone()).ok()
    }

    /// Saves a finished cell: appended to `cells.jsonl` and synced before this returns.
    pub fn put<T: Serialize>(&self, key: &str, value: &T) -> Result<()> {
        let value = serde_json::to_value(value).expect("cells serialize");
        let mut line = serde_json::to_vec(&CellLine {
            key: key.to_string(),
            value: value.clone(),
        })
        .expect("cells serialize");
        line.push(b'\n');
        let path = self.dir.join(CELLS);
        {
            let mut log = self.log.lock().expect("log lock");
            log.write_all(&line).map_err(|e| io(&path, e))?;
            log.sync_data().map_err(|e| io(&path, e))?;
        }
        self.cells
            .lock()
            .expect("cells lock")
            .insert(key.to_string(), value);
        // The wall time so far, so that a run killed before it finishes still accounts for it.
        self.write_run(false)
    }

    /// Writes `name` in the directory (atomically: a reader never sees half a file).
    pub fn write(&self, name: &str, bytes: &[u8]) -> Result<()> {
        write_atomic(&self.dir.join(name), bytes)
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Marks the run complete in `run.json`, with its wall time, and says where the results
    /// are.
    pub fn finish(&self) -> Result<()> {
        self.write_run(true)?;
        eprintln!(
            "wrote {} ({:.0} s of wall time over every invocation)",
            self.path("results.md").display(),
            self.wall_seconds()
        );
        Ok(())
    }

    fn write_run(&self, complete: bool) -> Result<()> {
        let run = RunInfo {
            updated: now(),
            wall_seconds: self.run.wall_seconds + self.started.elapsed().as_secs_f64(),
            complete,
            ..self.run.clone()
        };
        let json = serde_json::to_vec_pretty(&run).expect("run.json serializes");
        self.write(RUN, &json)
    }

    /// The wall time of every invocation so far, in seconds.
    pub fn wall_seconds(&self) -> f64 {
        self.run.wall_seconds + self.started.elapsed().as_secs_f64()
    }
}

/// An error unless `previous` is the same experiment with the same settings.
fn check_same(dir: &Path, previous: &RunInfo, experiment: &str, settings: &Value) -> Result<()> {
    let other = |what: String| {
        Err(Error::invalid(
            "out",
            format!(
                "{} holds a {} run with other settings ({what}); continue it with the same \
                 settings or choose another --out",
                dir.display(),
                previous.experiment
            ),
        ))
    };
    if previous.experiment != experiment {
        return other(format!("experiment {experiment} here"));
    }
    if let (Value::Object(now), Value::Object(then)) = (settings, &previous.settings) {
        for (key, value) in now {
            let before = then.get(key).unwrap_or(&Value::Null);
            if before != value {
                return other(format!("{key}: {value} here, {before} there"));
            }
        }
    }
    Ok(())
}

/// The cells of earlier invocations. A last line cut short by a kill is cut off the file
/// (its cell is computed again, and the next line starts clean); damage anywhere else is an
/// error.
fn read_cells(path: &Path) -> Result<BTreeMap<String, Value>> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(BTreeMap::new()),
        Err(e) => return Err(io(path, e)),
    };
    let whole = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    if whole < bytes.len() {
        let file = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|e| io(path, e))?;
        file.set_len(whole as u64).map_err(|e| io(path, e))?;
    }
    let mut cells = BTreeMap::new();
    for (i, line) in bytes[..whole].split(|&b| b == b'\n').enumerate() {
        if line.is_empty() {
            continue;
        }
        let c: CellLine = serde_json::from_slice(line)
            .map_err(|e| Error::corrupt(format!("cells.jsonl line {}", i + 1), e))?;
        cells.insert(c.key, c.value);
    }
    Ok(cells)
}
