//! Replaying the `trajectories.csv` that `deepfoids simulate` writes: one row
//! per fish per snapshot, `t,fish,behaviour,x,y,z,dx,dy,dz,speed,bl`, every
//! snapshot listing fish 0…n−1 in order.
//!
//! The CSV holds positions, headings and speeds only. Body lengths, behaviours
//! and dominance come from the scene rebuilt with the run's seed (`Env::new`
//! draws them from it), and every row's behaviour and body length must agree
//! with it — so a CSV is never drawn inside the wrong cage or with the wrong
//! fish. Chases and reward terms are not in the CSV; respawns are found as
//! jumps no swimming fish makes between two snapshots.

use crate::recording::{FLAG_RESPAWNED, FishSample, Info, Recording, ReplayError};
use deepfoids_env::Env;
use glam::Vec3;

/// The header `simulate` writes.
pub const HEADER: &str = "t,fish,behaviour,x,y,z,dx,dy,dz,speed,bl";

/// Body lengths in the CSV are rounded to 0.1 mm; allow twice that.
const BL_TOLERANCE: f32 = 2e-4;

struct Row {
    t: f64,
    fish: usize,
    position: Vec3,
    heading: Vec3,
    speed: f32,
}

/// A recording of the snapshots in `text` (the contents of `path`), every
/// `stride` snapshots so frames come `fps` times a second, for `env`'s school
/// (fresh from `Env::new` with the scene and seed of the run that wrote it).
pub fn from_trajectories(
    path: &str,
    text: &str,
    env: &Env,
    info: Info,
    fps: f64,
) -> Result<Recording, ReplayError> {
    if !(fps > 0.0 && fps.is_finite()) {
        return Err(ReplayError::Fps(fps));
    }
    let err = |line: usize, what: String| ReplayError::Csv {
        path: path.to_string(),
        line,
        what,
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim_end() == HEADER => {}
        Some((_, h)) => return Err(err(1, format!("header is `{h}`, expected `{HEADER}`"))),
        None => return Err(err(1, "the file is empty".into())),
    }
    let w = env.world();
    let n = w.len();
    let names: Vec<&str> = env.behaviours().iter().map(|b| b.name.as_str()).collect();
    // The farthest a fish of behaviour b swims in one second, with margin (as trajectories.png).
    let reach: Vec<f32> = env
        .scene()
        .behaviours
        .iter()
        .map(|b| b.species.speed_bl[1] * 1.6 * 3.0)
        .collect();

    let mut rec = Recording::new(env, info)?;
    let mut snapshot: Vec<Row> = Vec::with_capacity(n);
    let mut prev: Vec<Vec3> = vec![];
    let mut prev_t = f64::NAN;
    let mut jumped = vec![false; n];
    let mut stride = 0usize;
    let mut index = 0usize;
    let mut first_line = 0;
    for (k, line) in lines {
        let line_no = k + 1;
        if line.trim().is_empty() {
            continue;
        }
        if snapshot.is_empty() {
            first_line = line_no;
        }
        let row = parse_row(line).map_err(|what| err(line_no, what))?;
        let expected = snapshot.len();
        if row.fish != expected {
            return Err(err(
                line_no,
                format!(
                    "fish {} where fish {expected} was expected (each snapshot lists fish 0…{} in order)",
                    row.fish,
                    n - 1
                ),
            ));
        }
        let b = w.behaviour[row.fish] as usize;
        let behaviour = line.split(',').nth(2).unwrap_or_default();
        if behaviour != names[b] {
            return Err(ReplayError::Mismatch {
                path: path.into(),
                what: format!(
                    "line {line_no}: fish {} is `{behaviour}` here but `{}` in scene {} with seed {}: the CSV was written with another scene or seed",
                    row.fish,
                    names[b],
                    env.scene().id,
                    env.seed()
                ),
            });
        }
        let bl: f32 = line
            .rsplit(',')
            .next()
            .and_then(|x| x.trim().parse().ok())
            .unwrap_or(f32::NAN);
        if (bl - w.bl[row.fish]).abs() > BL_TOLERANCE {
            return Err(ReplayError::Mismatch {
                path: path.into(),
                what: format!(
                    "line {line_no}: fish {} is {bl} m long here but {:.4} m in scene {} with seed {}: the CSV was written with another scene or seed",
                    row.fish,
                    w.bl[row.fish],
                    env.scene().id,
                    env.seed()
                ),
            });
        }
        if row.fish > 0 && row.t != snapshot[0].t {
            return Err(err(
                line_no,
                format!(
                    "t = {} inside the snapshot that began at t = {} (line {first_line})",
                    row.t, snapshot[0].t
                ),
            ));
        }
        snapshot.push(row);
        if snapshot.len() < n {
            continue;
        }
        // A complete snapshot.
        let t = snapshot[0].t;
        let pos: Vec<Vec3> = snapshot.iter().map(|r| r.position).collect();
        let head: Vec<Vec3> = snapshot.iter().map(|r| r.heading).collect();
        if !prev.is_empty() {
            let dt = (t - prev_t) as f32;
            if dt <= 0.0 {
                return Err(err(
                    first_line,
                    format!("t = {t} does not follow t = {prev_t}"),
                ));
            }
            if stride == 0 {
                stride = ((1.0 / (fps * dt as f64)).round() as usize).max(1);
            }
            for i in 0..n {
                let limit = reach[w.behaviour[i] as usize] * w.bl[i] * dt + 0.5 * w.bl[i];
                jumped[i] |= pos[i].distance(prev[i]) > limit;
            }
        }
        let (p, m) = crate::recording::school_order(&pos, &head);
        rec.curves.push(t, p, m);
        if index == 0 || (stride > 0 && index.is_multiple_of(stride)) {
            let fish = snapshot.iter().map(|r| FishSample {
                position: r.position,
                heading: r.heading,
                speed: r.speed,
                flags: if jumped[r.fish] { FLAG_RESPAWNED } else { 0 },
            });
            rec.push_frame(t, fish, None, None);
            jumped.iter_mut().for_each(|j| *j = false);
        }
        index += 1;
        prev = pos;
        prev_t = t;
        snapshot.clear();
    }
    if !snapshot.is_empty() {
        return Err(err(
            first_line,
            format!(
                "the last snapshot (t = {}) lists {} of {n} fish",
                snapshot[0].t,
                snapshot.len()
            ),
        ));
    }
    if rec.frames() < 2 {
        return Err(err(
            1,
            format!(
                "{} complete snapshot(s); a replay needs two at least",
                rec.frames()
            ),
        ));
    }
    Ok(rec)
}

fn parse_row(line: &str) -> Result<Row, String> {
    let cols: Vec<&str> = line.split(',').collect();
    if cols.len() != 11 {
        return Err(format!("{} columns, expected 11 ({HEADER})", cols.len()));
    }
    let f = |i: usize| -> Result<f32, String> {
        let v: f32 = cols[i].trim().parse().map_err(|_| {
            format!(
                "column {} is `{}`, not a number",
                HEADER.split(',').nth(i).unwrap_or("?"),
                cols[i]
            )
        })?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!(
                "column {} is {v}; numbers must be finite",
                HEADER.split(',').nth(i).unwrap_or("?")
            ))
        }
    };
    let t: f64 = cols[0]
        .trim()
        .parse()
        .map_err(|_| format!("column t is `{}`, not a number", cols[0]))?;
    let fish: usize = cols[1]
        .trim()
        .parse()
        .map_err(|_| format!("column fish is `{}`, not a fish index", cols[1]))?;
    let heading = Vec3::new(f(6)?, f(7)?, f(8)?);
    if (heading.length() - 1.0).abs() > 0.01 {
        return Err(format!(
            "heading ({}, {}, {}) is not a unit vector",
            heading.x, heading.y, heading.z
        ));
    }
    Ok(Row {
        t,
        fish,
        position: Vec3::new(f(3)?, f(4)?, f(5)?),
        heading: heading.normalize(),
        speed: f(9)?,
    })
}
