//! TensorBoard event files: read them back, and cut them at a resumed step.
//!
//! An event file is a sequence of TFRecords — `u64` length, `u32` masked
//! CRC-32C of the length, the payload, `u32` masked CRC-32C of the payload,
//! all little-endian — each payload an `Event` protobuf (`wall_time` = 1,
//! `step` = 2, `summary` = 5 holding `value` = 1 entries of `tag` = 1 and
//! `simple_value` = 2; the fields this module reads).
//!
//! # Resume (issue 13 item 3)
//! A killed run has logged points after its last checkpoint; the resumed run
//! logs those steps again. TensorBoard would show two values at one step, so
//! [`truncate_after`] rewrites each event file of the behaviour keeping only
//! the records at or before the checkpoint's step (and drops a record cut
//! short by the kill), atomically — as ML-Agents and TensorBoard's own
//! `purge` of orphaned data do. The resumed run then writes a new file.

use crate::error::{LearnError, Result};
use std::path::{Path, PathBuf};
use tensorboard_rs::masked_crc32c::masked_crc32c;

/// `Event` with the fields read here (prost skips the others).
#[derive(Clone, PartialEq, prost::Message)]
struct Event {
    #[prost(int64, tag = "2")]
    step: i64,
    #[prost(message, optional, tag = "5")]
    summary: Option<Summary>,
}

#[derive(Clone, PartialEq, prost::Message)]
struct Summary {
    #[prost(message, repeated, tag = "1")]
    value: Vec<Value>,
}

#[derive(Clone, PartialEq, prost::Message)]
struct Value {
    #[prost(string, tag = "1")]
    tag: String,
    #[prost(float, optional, tag = "2")]
    simple_value: Option<f32>,
}

/// One scalar point of an event file.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    pub tag: String,
    pub step: i64,
    pub value: f32,
}

/// A record with its framing, and its payload.
type Record<'a> = (&'a [u8], &'a [u8]);

/// The whole records of `bytes` as `(record bytes with framing, payload)`,
/// and whether the file ends in a broken or partial record (a kill
/// mid-write, or damage): reading stops there.
fn records(bytes: &[u8]) -> (Vec<Record<'_>>, bool) {
    let mut out = vec![];
    let mut at = 0;
    while at < bytes.len() {
        let rest = &bytes[at..];
        if rest.len() < 12 {
            return (out, true);
        }
        let len_bytes: [u8; 8] = rest[..8].try_into().expect("8 bytes");
        let len_crc = u32::from_le_bytes(rest[8..12].try_into().expect("4 bytes"));
        if masked_crc32c(&len_bytes) != len_crc {
            return (out, true);
        }
        let len = u64::from_le_bytes(len_bytes);
        let Some(total) = usize::try_from(len)
            .ok()
            .and_then(|l| l.checked_add(16))
            .filter(|&t| t <= rest.len())
        else {
            return (out, true);
        };
        let payload = &rest[12..total - 4];
        let crc = u32::from_le_bytes(rest[total - 4..total].try_into().expect("4 bytes"));
        if masked_crc32c(payload) != crc {
            return (out, true);
        }
        out.push((&rest[..total], payload));
        at += total;
    }
    (out, false)
}

/// The event files of a folder, by name (TensorBoard's reading order).
pub fn event_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().contains("tfevents"))
            })
            .collect(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => vec![],
        Err(e) => return Err(LearnError::io(dir)(e)),
    };
    files.sort();
    Ok(files)
}

fn decode(path: &Path, payload: &[u8]) -> Result<Event> {
    <Event as prost::Message>::decode(payload).map_err(|e| LearnError::Corrupt {
        path: path.to_path_buf(),
        reason: format!("not a TensorBoard event: {e}"),
    })
}

/// Every scalar point of the event files in `dir`, in reading order; a
/// broken record is an error.
pub fn scalars(dir: &Path) -> Result<Vec<Point>> {
    let mut out = vec![];
    for path in event_files(dir)? {
        let bytes = std::fs::read(&path).map_err(LearnError::io(&path))?;
        let (recs, broken) = records(&bytes);
        if broken {
            return Err(LearnError::Corrupt {
                path,
                reason: format!("a broken TFRecord after {} whole ones", recs.len()),
            });
        }
        for (_, payload) in recs {
            let event = decode(&path, payload)?;
            for v in event.summary.map(|s| s.value).unwrap_or_default() {
                if let Some(value) = v.simple_value {
                    out.push(Point {
                        tag: v.tag,
                        step: event.step,
                        value,
                    });
                }
            }
        }
    }
    Ok(out)
}

/// Rewrite the event files of `dir` keeping only the records at steps
/// `≤ step` (see the module documentation); each file is replaced
/// atomically, and left alone when it has nothing to drop. Returns the
/// records dropped.
pub fn truncate_after(dir: &Path, step: u64) -> Result<usize> {
    let mut dropped = 0;
    for path in event_files(dir)? {
        let bytes = std::fs::read(&path).map_err(LearnError::io(&path))?;
        let (recs, broken) = records(&bytes);
        let mut kept = Vec::with_capacity(bytes.len());
        let mut cut = broken as usize;
        for (record, payload) in recs {
            let event = decode(&path, payload)?;
            if event.step <= step as i64 {
                kept.extend_from_slice(record);
            } else {
                cut += 1;
            }
        }
        if cut > 0 {
            deepfoids_io::write_atomic(&path, &kept).map_err(LearnError::io(&path))?;
            dropped += cut;
        }
    }
    Ok(dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tensorboard_rs::summary_writer::SummaryWriter;

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("tfevents-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// Points written by tensorboard-rs read back as written; cutting at step
    /// 20 keeps steps 10 and 20 (and the file-version record), drops 30 and
    /// 40, and a record cut short at the end (a kill mid-write) goes too.
    #[test]
    fn read_back_and_cut_after_a_step() {
        let dir = temp("cut");
        {
            let mut w = SummaryWriter::new(&dir);
            for step in [10, 20, 30, 40] {
                w.add_scalar("Losses/Policy Loss", step as f32 / 10.0, step);
                w.add_scalar("Policy/Entropy", -(step as f32), step);
            }
            w.flush();
        }
        let points = scalars(&dir).unwrap();
        assert_eq!(points.len(), 8);
        assert_eq!(
            points[3],
            Point {
                tag: "Policy/Entropy".into(),
                step: 20,
                value: -20.0
            }
        );
        // A kill mid-write: half a record at the end.
        let file = &event_files(&dir).unwrap()[0];
        let mut bytes = std::fs::read(file).unwrap();
        let whole = bytes.len();
        let half = bytes[whole - 30..whole - 10].to_vec();
        bytes.extend_from_slice(&half);
        std::fs::write(file, &bytes).unwrap();
        assert!(scalars(&dir).is_err(), "a broken record is an error");

        assert_eq!(truncate_after(&dir, 20).unwrap(), 4 + 1);
        let steps: Vec<(String, i64)> = scalars(&dir)
            .unwrap()
            .into_iter()
            .map(|p| (p.tag, p.step))
            .collect();
        assert_eq!(
            steps,
            vec![
                ("Losses/Policy Loss".into(), 10),
                ("Policy/Entropy".into(), 10),
                ("Losses/Policy Loss".into(), 20),
                ("Policy/Entropy".into(), 20)
            ]
        );
        let size = std::fs::metadata(file).unwrap().len();
        assert_eq!(truncate_after(&dir, 20).unwrap(), 0, "nothing more to cut");
        assert_eq!(std::fs::metadata(file).unwrap().len(), size);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
