//! Replay pages of a school (`deepfoids replay`, `eval --replay`): writing
//! the page, its memory check, the lines that describe it, and the check
//! that an evaluation simulated again reproduces its saved P and M.

use crate::evaluate::{Evaluation, evaluate};
use anyhow::{Context, Result, bail};
use deepfoids_env::{Env, Policy};
use deepfoids_io::write_atomic;
use deepfoids_replay::{EnvRecorder, Info, PageSize, Recording, page};
use std::path::Path;

/// Write `rec` as a replay page at `path` (atomically).
pub fn write_page(path: &Path, rec: &Recording) -> Result<PageSize> {
    let (html, size) = page(rec);
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    write_atomic(path, html.as_bytes())?;
    Ok(size)
}

/// [`evaluate`], recording a replay at `fps` frames per simulated second
/// from the first recorded tick when `info` describes one (`None`: no
/// recording). Check its memory first with [`check_recording`].
pub fn evaluate_recorded(
    env: &mut Env,
    policy: &mut dyn Policy,
    warmup: f64,
    seconds: f64,
    info: Option<Info>,
    fps: f64,
) -> Result<(Evaluation, Option<Recording>)> {
    let mut recorder = None;
    let mut record_error = None;
    let eval = evaluate(env, policy, warmup, seconds, |env, tick, _| {
        match (&info, recorder.as_mut()) {
            (Some(info), None) if tick == 0 => match EnvRecorder::new(env, info.clone(), fps) {
                Ok(r) => recorder = Some(r),
                Err(e) => record_error = Some(e),
            },
            (_, Some(r)) => r.observe(env),
            _ => {}
        }
    })?;
    if let Some(e) = record_error {
        return Err(e.into());
    }
    let rec = recorder.map(|r| r.finish(curves(&eval)));
    Ok((eval, rec))
}

/// Peak bytes per fish and frame while a page is built: the recording (27 B
/// with the reward terms), its encoded copy (27), the gzip stream (at most
/// 27), its base64 text (36) and the page that holds it (36) — 153, rounded up.
pub const PAGE_BYTES_PER_FISH_FRAME: u64 = 160;

/// A CSV row of `trajectories.csv` is at least this long (bytes).
pub const MIN_CSV_ROW: u64 = 60;

/// Refuse a replay whose page would not fit into memory (`deepfoids_env::memory`).
pub fn check_recording(env: &Env, seconds: f64, fps: f64) -> Result<()> {
    let stride = deepfoids_replay::stride(fps, env.tick_seconds())?;
    let frames = (seconds / (stride as f64 * env.tick_seconds())).floor() as u64 + 1;
    let fish = env.world().len() as u64;
    deepfoids_env::memory::check(
        &format!("a replay of {fish} fish × {frames} frames"),
        frames * fish * PAGE_BYTES_PER_FISH_FRAME,
        "lower --seconds or --fps",
    )?;
    Ok(())
}

/// One line on what was written.
pub fn describe(path: &Path, rec: &Recording, size: &PageSize) -> String {
    let span = rec.times.last().copied().unwrap_or(0.0) - rec.times[0];
    format!(
        "wrote {}: {} frames × {} fish over {:.1} s ({:.2} frames/s); {} (recording {} gzipped from {}, three.js {})",
        path.display(),
        rec.frames(),
        rec.fish,
        span,
        (rec.frames() - 1) as f64 / span.max(1e-9) as f64,
        bytes(size.total),
        bytes(size.data_gzip),
        bytes(size.data_raw),
        bytes(size.library),
    )
}

/// Browsers load pages of a few hundred MB slowly or not at all.
pub const LARGE_PAGE: usize = 200_000_000;

/// Say so when a page is too large to open comfortably.
pub fn warn_if_large(size: &PageSize) {
    if size.total > LARGE_PAGE {
        eprintln!(
            "warning: a {} page loads slowly and may not open at all; lower --fps or --seconds (size grows with fish × frames, about 13 bytes each before gzip, 27 with reward terms)",
            bytes(size.total)
        );
    }
}

/// A byte count for people: `5.9 MB`, `48 kB`.
pub fn bytes(n: usize) -> String {
    if n >= 1_000_000 {
        format!("{:.1} MB", n as f64 / 1e6)
    } else {
        format!("{:.0} kB", n as f64 / 1e3)
    }
}

/// The viewer's title block for `env`'s scene driven by `policy`.
pub fn info(env: &Env, policy: &str, source: &str, notes: Vec<String>) -> Info {
    let s = env.scene();
    Info {
        title: format!("{} · {} · seed {}", s.id, policy, env.seed()),
        scene: s.id.clone(),
        description: s.description.clone(),
        policy: policy.to_string(),
        seed: env.seed(),
        phase: s.phase.as_str().to_string(),
        source: source.to_string(),
        notes,
    }
}

/// `(t, P, M)` of every sample of an evaluation.
pub fn curves(eval: &Evaluation) -> impl Iterator<Item = (f64, f32, f32)> + '_ {
    eval.recorder.samples.iter().map(|s| (s.t, s.p, s.m))
}

/// `(t, P, M)` as `metrics.csv` prints them.
pub fn read_pm(path: &Path) -> Result<Vec<[String; 3]>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    if !header.starts_with("t,P,M,") {
        bail!(
            "{}: header `{header}` does not start with t,P,M",
            path.display()
        );
    }
    lines
        .enumerate()
        .map(|(k, l)| {
            let mut c = l.split(',');
            match (c.next(), c.next(), c.next()) {
                (Some(t), Some(p), Some(m)) => Ok([t.into(), p.into(), m.into()]),
                _ => bail!("{}: line {}: fewer than 3 columns", path.display(), k + 2),
            }
        })
        .collect()
}

/// Every tick's P and M of the re-run must print as the saved ones.
pub fn check_pm(path: &Path, saved: &[[String; 3]], eval: &Evaluation) -> Result<()> {
    let samples = &eval.recorder.samples;
    if samples.len() != saved.len() {
        bail!(
            "the re-run has {} samples but {} has {}: the evaluation cannot be reproduced",
            samples.len(),
            path.display(),
            saved.len()
        );
    }
    for (s, row) in samples.iter().zip(saved) {
        let now = [
            format!("{:.3}", s.t),
            format!("{:.5}", s.p),
            format!("{:.5}", s.m),
        ];
        if &now != row {
            bail!(
                "the re-run does not reproduce {} at t = {} s: (t, P, M) = ({}, {}, {}) now, ({}, {}, {}) saved — the policy, scene or code changed since the evaluation",
                path.display(),
                row[0],
                now[0],
                now[1],
                now[2],
                row[0],
                row[1],
                row[2]
            );
        }
    }
    Ok(())
}

/// Read a JSON file as `T`, naming the file in every error.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not the expected JSON", path.display()))
}
