//! Scalars for TensorBoard (tensorboard-rs; one event folder per behaviour,
//! ML-Agents' names) and the same scalars in `scalars.csv`, flushed at every
//! log point so a long run's CSV grows as it trains.
//!
//! tensorboard-rs writes on a background thread: [`Logger::close`] (or drop)
//! flushes and drops the writers before the process exits. Its `add_text` and
//! `add_hparams` panic (unimplemented), so only scalars are written.

use crate::error::{LearnError, Result};
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use tensorboard_rs::summary_writer::SummaryWriter;

pub struct Logger {
    writers: Vec<SummaryWriter>,
    names: Vec<String>,
    csv: BufWriter<File>,
    csv_path: PathBuf,
}

impl Logger {
    /// Open (or continue) the logs of `run_dir` for the named behaviours.
    pub fn open(run_dir: &Path, behaviours: &[String]) -> Result<Self> {
        let csv_path = run_dir.join("scalars.csv");
        let fresh = !csv_path.exists();
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&csv_path)
            .map_err(LearnError::io(&csv_path))?;
        let mut csv = BufWriter::new(file);
        if fresh {
            writeln!(csv, "behaviour,step,tag,value").map_err(LearnError::io(&csv_path))?;
        }
        let writers = behaviours
            .iter()
            .map(|b| {
                let dir = run_dir.join("tb").join(b);
                std::fs::create_dir_all(&dir).map_err(LearnError::io(&dir))?;
                Ok(SummaryWriter::new(&dir))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            writers,
            names: behaviours.to_vec(),
            csv,
            csv_path,
        })
    }

    /// One scalar of behaviour `b` at agent step `step` (non-finite values are skipped).
    pub fn scalar(&mut self, b: usize, tag: &str, value: f64, step: u64) -> Result<()> {
        if !value.is_finite() {
            return Ok(());
        }
        self.writers[b].add_scalar(tag, value as f32, step as usize);
        writeln!(self.csv, "{},{},{},{}", self.names[b], step, tag, value)
            .map_err(LearnError::io(&self.csv_path))
    }

    pub fn flush(&mut self) -> Result<()> {
        for w in &mut self.writers {
            w.flush();
        }
        self.csv.flush().map_err(LearnError::io(&self.csv_path))
    }

    /// Flush and close the writers (waits for tensorboard-rs' background writes).
    pub fn close(mut self) -> Result<()> {
        self.flush()?;
        self.writers.clear();
        Ok(())
    }
}

/// Where an algorithm writes its scalars for one behaviour at one step.
pub struct Scalars<'a> {
    pub logger: &'a mut Logger,
    pub behaviour: usize,
    pub step: u64,
}

impl Scalars<'_> {
    pub fn put(&mut self, tag: &str, value: f64) -> Result<()> {
        self.logger.scalar(self.behaviour, tag, value, self.step)
    }
}
