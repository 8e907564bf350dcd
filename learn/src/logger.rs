//! Scalars for TensorBoard (tensorboard-rs; one event folder per behaviour,
//! ML-Agents' names) and the same scalars in `scalars.csv`, flushed at every
//! log point so a long run's CSV grows as it trains.
//!
//! tensorboard-rs writes on a background thread: [`Logger::close`] (or drop)
//! flushes and drops the writers before the process exits. Its `add_text` and
//! `add_hparams` panic (unimplemented), so only scalars are written.
//!
//! On resume the logs are first cut back to the checkpoint (issue 13 item 3):
//! each behaviour's event files keep only the points at or before its
//! checkpoint step ([`crate::tfevents::truncate_after`]) and `scalars.csv`
//! only its rows up to there, both rewritten atomically, so that TensorBoard
//! and the CSV hold one value per tag and step however often a run was
//! killed and resumed.

use crate::error::{LearnError, Result};
use std::collections::BTreeMap;
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
    /// Open the logs of `run_dir` for the named behaviours; `resumed_at`:
    /// continue them from each behaviour's checkpoint step (later points are
    /// removed first).
    pub fn open(run_dir: &Path, behaviours: &[String], resumed_at: Option<&[u64]>) -> Result<Self> {
        let csv_path = run_dir.join("scalars.csv");
        if let Some(steps) = resumed_at {
            let at: BTreeMap<&str, u64> = behaviours
                .iter()
                .map(String::as_str)
                .zip(steps.iter().copied())
                .collect();
            for (b, &step) in &at {
                crate::tfevents::truncate_after(&run_dir.join("tb").join(b), step)?;
            }
            truncate_csv(&csv_path, &at)?;
            // tensorboard-rs names a file by second and PID: a resume within
            // the second of the last file (in one process) would overwrite it.
            for b in behaviours {
                wait_past_newest(&run_dir.join("tb").join(b))?;
            }
        }
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

/// Keep the header and the rows of `scalars.csv` at or before their
/// behaviour's step in `at` (rows of other behaviours stay; a line cut short
/// by a kill goes); rewritten atomically when anything goes.
fn truncate_csv(path: &Path, at: &BTreeMap<&str, u64>) -> Result<()> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(LearnError::io(path)(e)),
    };
    let mut kept = String::with_capacity(text.len());
    let mut lines = text.split_inclusive('\n');
    if let Some(header) = lines.next() {
        kept.push_str(header);
    }
    for line in lines {
        let mut f = line.splitn(4, ',');
        let (b, step, tag, value) = (f.next(), f.next(), f.next(), f.next());
        let whole = tag.is_some() && value.is_some_and(|v| v.ends_with('\n'));
        let step: Option<u64> = step.and_then(|s| s.parse().ok());
        let keep = match (b, step) {
            (Some(b), Some(step)) if whole => at.get(b).is_none_or(|&max| step <= max),
            _ => false,
        };
        if keep {
            kept.push_str(line);
        }
    }
    if kept.len() != text.len() {
        deepfoids_io::write_atomic(path, kept.as_bytes()).map_err(LearnError::io(path))?;
    }
    Ok(())
}

/// Sleep until the clock is past the second in the name of the newest event
/// file of `dir` (`events.out.tfevents.<seconds>.…`).
fn wait_past_newest(dir: &Path) -> Result<()> {
    let newest = crate::tfevents::event_files(dir)?
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            name.strip_prefix("events.out.tfevents.")?
                .split('.')
                .next()?
                .parse::<u64>()
                .ok()
        })
        .max();
    let now = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs())
    };
    if let Some(t) = newest {
        while now() <= t {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Cut back to step 20 for `a` and 10 for `b`: later rows go, rows of a
    /// behaviour not in the run stay, and a line cut short by a kill goes.
    #[test]
    fn csv_cut_back_to_the_checkpoint() {
        let path = std::env::temp_dir().join(format!("scalars-{}.csv", std::process::id()));
        std::fs::write(
            &path,
            "behaviour,step,tag,value\na,10,x,1\nb,10,x,2\na,20,Losses/Q1 Loss,3\nb,20,x,4\nc,90,x,5\na,30,x,6\na,40,x,",
        )
        .unwrap();
        let at = BTreeMap::from([("a", 20), ("b", 10)]);
        truncate_csv(&path, &at).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "behaviour,step,tag,value\na,10,x,1\nb,10,x,2\na,20,Losses/Q1 Loss,3\nc,90,x,5\n"
        );
        let _ = std::fs::remove_file(&path);
    }
}
