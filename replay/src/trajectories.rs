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

/// Write `out`'s fish as rows of `trajectories.csv` (under [`HEADER`]);
/// `names[b]` is behaviour `b`'s name.
pub fn write_rows<W: std::io::Write>(
    w: &mut W,
    out: &deepfoids_env::StepOutput,
    names: &[String],
) -> std::io::Result<()> {
    let f = &out.fish;
    for i in 0..f.position.len() {
        let (p, d) = (f.position[i], f.heading[i]);
        writeln!(
            w,
            "{:.3},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
            out.time,
            i,
            names[f.behaviour[i] as usize],
            p.x,
            p.y,
            p.z,
            d.x,
            d.y,
            d.z,
            f.speed[i],
            f.bl[i]
        )?;
    }
    Ok(())
}

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
        check_fish(path, line, line_no, row.fish, env, &names)?;
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

/// The fish on line `line_no` must be of the behaviour and body length that
/// `env`'s scene and seed give fish `fish`: a CSV written with another scene
/// or seed is refused.
fn check_fish(
    path: &str,
    line: &str,
    line_no: usize,
    fish: usize,
    env: &Env,
    names: &[&str],
) -> Result<(), ReplayError> {
    let w = env.world();
    let b = w.behaviour[fish] as usize;
    let behaviour = line.split(',').nth(2).unwrap_or_default();
    if behaviour != names[b] {
        return Err(ReplayError::Mismatch {
            path: path.into(),
            what: format!(
                "line {line_no}: fish {} is `{behaviour}` here but `{}` in scene {} with seed {}: the CSV was written with another scene or seed",
                fish,
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
    if (bl - w.bl[fish]).abs() > BL_TOLERANCE {
        return Err(ReplayError::Mismatch {
            path: path.into(),
            what: format!(
                "line {line_no}: fish {} is {bl} m long here but {:.4} m in scene {} with seed {}: the CSV was written with another scene or seed",
                fish,
                w.bl[fish],
                env.scene().id,
                env.seed()
            ),
        });
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::tests::env;
    use deepfoids_env::policy::action_buffers;
    use deepfoids_env::{Policy, RandomPolicy};

    fn info() -> Info {
        Info {
            title: "t".into(),
            scene: "seabream_50".into(),
            description: String::new(),
            policy: "random".into(),
            seed: 3,
            phase: "pretrain".into(),
            source: "csv".into(),
            notes: vec![],
        }
    }

    /// 2 s of random actions written as `simulate` writes them (every 0.1 s
    /// tick), and the positions at every tick.
    fn csv(seconds: u64) -> (String, Vec<Vec<Vec3>>) {
        let mut env = env("seabream_50", 3);
        let mut policy = RandomPolicy { seed: 3 };
        let mut actions = action_buffers(&env);
        let names: Vec<String> = env.behaviours().iter().map(|b| b.name.clone()).collect();
        let mut text = format!("{HEADER}\n").into_bytes();
        let mut positions = vec![];
        let mut write = |env: &Env, text: &mut Vec<u8>| {
            write_rows(text, env.output(), &names).unwrap();
            positions.push(env.output().fish.position.clone());
        };
        write(&env, &mut text);
        for _ in 0..seconds * 10 {
            policy.act(&env, &mut actions).unwrap();
            env.step(&actions).unwrap();
            write(&env, &mut text);
        }
        (String::from_utf8(text).unwrap(), positions)
    }

    /// Rows every 0.1 s at 5 frames/s: every second snapshot is a frame
    /// (t = 0, 0.2, … 2.0), each fish within a millimetre (the CSV's 0.1 mm
    /// plus the recording's 1 mm steps); P and M at every snapshot.
    #[test]
    fn reads_what_simulate_writes() {
        let (text, positions) = csv(2);
        let e = env("seabream_50", 3);
        let r = from_trajectories("trajectories.csv", &text, &e, info(), 5.0).unwrap();
        assert_eq!(r.frames(), 11);
        assert_eq!(r.curves.t.len(), 21);
        assert!((r.times[3] - 0.6).abs() < 1e-6);
        for f in 0..r.frames() {
            for (i, p) in positions[2 * f].iter().enumerate() {
                let d = r.position_at(f, i).distance(*p);
                assert!(d < 0.001, "frame {f} fish {i}: {d} m off");
            }
        }
        let (p, m) = crate::recording::school_order(&positions[4], &{
            // Headings as printed; P and M of snapshot 4 from the CSV's own numbers.
            text.lines()
                .skip(1 + 4 * 50)
                .take(50)
                .map(|l| {
                    let c: Vec<f32> = l
                        .split(',')
                        .skip(6)
                        .take(3)
                        .map(|x| x.parse().unwrap())
                        .collect();
                    Vec3::new(c[0], c[1], c[2]).normalize()
                })
                .collect::<Vec<_>>()
        });
        assert!((r.curves.p[4] - p).abs() < 1e-3 && (r.curves.m[4] - m).abs() < 1e-3);
        assert!(r.terms.is_empty() && !r.has_chases);
    }

    /// Another seed draws other body lengths: the CSV is refused, naming the fish.
    #[test]
    fn refuses_a_csv_of_another_seed() {
        let (text, _) = csv(1);
        let other = env("seabream_50", 4);
        let err = from_trajectories("runs/x/trajectories.csv", &text, &other, info(), 5.0)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("runs/x/trajectories.csv: line 2: fish 0 is"),
            "{err}"
        );
        assert!(err.contains("another scene or seed"), "{err}");
    }

    #[test]
    fn refuses_broken_files_naming_the_line() {
        let (text, _) = csv(1);
        let e = env("seabream_50", 3);
        let read = |t: &str| {
            from_trajectories("t.csv", t, &e, info(), 5.0)
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            read("t,fish\n"),
            "t.csv: line 1: header is `t,fish`, expected `t,fish,behaviour,x,y,z,dx,dy,dz,speed,bl`"
        );
        // Cut in the middle of the third snapshot (lines 102–151).
        let cut: String = text
            .lines()
            .take(1 + 2 * 50 + 3)
            .map(|l| format!("{l}\n"))
            .collect();
        assert_eq!(
            read(&cut),
            "t.csv: line 102: the last snapshot (t = 0.2) lists 3 of 50 fish"
        );
        let swapped = text.replacen("\n0.000,1,", "\n0.000,7,", 1);
        assert_eq!(
            read(&swapped),
            "t.csv: line 3: fish 7 where fish 1 was expected (each snapshot lists fish 0…49 in order)"
        );
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut cols: Vec<&str> = lines[5].split(',').collect();
        cols[7] = "0.9";
        lines[5] = cols.join(",");
        assert!(
            read(&lines.join("\n")).starts_with("t.csv: line 6: heading ("),
            "not a unit vector"
        );
    }
}
