//! Scalars for TensorBoard (tensorboard-rs; one event folder per behaviour,
//! ML-Agents' names) and the same scalars in `scalars.csv`.
//!
//! tensorboard-rs writes on a background thread: [`Logger::close`] (or drop)
//! flushes and drops the writers before the process exits. Its `add_text` and
//! `add_hparams` panic (unimplemented), so only scalars are written.

use anyhow::{Context, Result};
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::Path;
use tensorboard_rs::summary_writer::SummaryWriter;

pub struct Logger {
    writers: Vec<SummaryWriter>,
    names: Vec<String>,
    csv: BufWriter<File>,
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
            .with_context(|| format!("cannot open {}", csv_path.display()))?;
        let mut csv = BufWriter::new(file);
        if fresh {
            writeln!(csv, "behaviour,step,tag,value")?;
        }
        let writers = behaviours
            .iter()
            .map(|b| {
                let dir = run_dir.join("tb").join(b);
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("cannot create {}", dir.display()))?;
                Ok(SummaryWriter::new(&dir))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            writers,
            names: behaviours.to_vec(),
            csv,
        })
    }

    /// One scalar of behaviour `b` at agent step `step`.
    pub fn scalar(&mut self, b: usize, tag: &str, value: f64, step: u64) -> Result<()> {
        if !value.is_finite() {
            return Ok(());
        }
        self.writers[b].add_scalar(tag, value as f32, step as usize);
        writeln!(self.csv, "{},{},{},{}", self.names[b], step, tag, value)?;
        Ok(())
    }

    pub fn flush(&mut self) -> Result<()> {
        for w in &mut self.writers {
            w.flush();
        }
        self.csv.flush()?;
        Ok(())
    }

    /// Flush and close the writers (waits for tensorboard-rs' background writes).
    pub fn close(mut self) -> Result<()> {
        self.flush()?;
        self.writers.clear();
        Ok(())
    }
}
