//! Progress of a run: a bar on a terminal; a line every `every` agent steps of
//! each behaviour when stdout is not a terminal (nohup, CI, a cluster job), as
//! ML-Agents prints its summaries:
//!
//! ```text
//! coho_regular: step 50,000/4,000,000 · 123 s · 1,234 agent-steps/s · cumulative reward 12.3 ± 4.5 (37 episodes) · reward/decision 0.412 · P 0.31 · M 0.12
//! ```

use crate::stats::ProgressSummary;
use std::io::{IsTerminal, Write};
use std::time::Instant;

/// How a run reports its progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgressMode {
    /// A bar when stdout is a terminal, else lines.
    Auto,
    /// Lines (whatever stdout is).
    Lines,
    /// Nothing.
    Quiet,
}

/// A number with thousands separators: 4,000,000.
pub fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// One progress line (see the module documentation).
pub fn line(
    behaviour: &str,
    steps: u64,
    budget: u64,
    elapsed: f64,
    rate: f64,
    s: &ProgressSummary,
) -> String {
    let reward = match s.cumulative_reward {
        Some((mean, sd)) => format!(
            "cumulative reward {mean:.1} ± {sd:.1} ({} episodes)",
            thousands(s.episodes)
        ),
        None => "cumulative reward – (no episode ended)".into(),
    };
    format!(
        "{behaviour}: step {}/{} · {elapsed:.0} s · {} agent-steps/s · {reward} · reward/decision {:.3} · P {:.2} · M {:.2}",
        thousands(steps),
        thousands(budget),
        thousands(rate.round() as u64),
        s.reward_per_decision,
        s.p,
        s.m
    )
}

/// The progress reporter of a run.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    lines: Option<Box<dyn Write + Send>>,
    every: u64,
    next: Vec<u64>,
    started: Instant,
}

impl Progress {
    /// For behaviours at `steps` (their own agent steps) of `budget` in all;
    /// lines every `every` steps of a behaviour go to `sink` (stdout if `None`).
    pub fn new(
        mode: ProgressMode,
        budget: u64,
        done: u64,
        steps: &[u64],
        every: u64,
        sink: Option<Box<dyn Write + Send>>,
    ) -> Self {
        let lines_mode = match mode {
            ProgressMode::Quiet => false,
            ProgressMode::Lines => true,
            ProgressMode::Auto => !std::io::stdout().is_terminal(),
        };
        let every = every.max(1);
        let bar = (mode == ProgressMode::Auto && !lines_mode).then(|| {
            let bar = indicatif::ProgressBar::new(budget);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:30} {pos}/{len} steps · {per_sec} · ETA {eta} · {msg}",
                )
                .expect("a valid template"),
            );
            bar.set_position(done);
            bar
        });
        Self {
            bar,
            lines: lines_mode.then(|| sink.unwrap_or_else(|| Box::new(std::io::stdout()))),
            every,
            next: steps.iter().map(|s| (s / every + 1) * every).collect(),
            started: Instant::now(),
        }
    }

    /// Whether behaviour `b` at `steps` is due a line.
    pub fn line_due(&self, b: usize, steps: u64) -> bool {
        self.lines.is_some() && steps >= self.next[b]
    }

    /// Print behaviour `b`'s line; `rate` is the run's agent-steps/s so far.
    pub fn print_line(
        &mut self,
        b: usize,
        name: &str,
        steps: u64,
        budget: u64,
        rate: f64,
        summary: &ProgressSummary,
    ) {
        let elapsed = self.started.elapsed().as_secs_f64();
        if let Some(out) = &mut self.lines {
            let _ = writeln!(out, "{}", line(name, steps, budget, elapsed, rate, summary));
            let _ = out.flush();
        }
        while self.next[b] <= steps {
            self.next[b] += self.every;
        }
    }

    pub fn set_position(&self, done: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(done);
        }
    }

    pub fn message(&self, msg: String) {
        if let Some(bar) = &self.bar {
            bar.set_message(msg);
        }
    }

    pub fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_reads_like_ml_agents_summary() {
        assert_eq!(thousands(4_000_000), "4,000,000");
        assert_eq!(thousands(999), "999");
        let s = ProgressSummary {
            decisions: 50_000,
            episodes: 37,
            cumulative_reward: Some((12.34, 4.56)),
            reward_per_decision: 0.4123,
            p: 0.312,
            m: 0.118,
        };
        assert_eq!(
            line("coho_regular", 50_000, 4_000_000, 123.4, 1234.4, &s),
            "coho_regular: step 50,000/4,000,000 · 123 s · 1,234 agent-steps/s · cumulative reward 12.3 ± 4.6 (37 episodes) · reward/decision 0.412 · P 0.31 · M 0.12"
        );
    }
}
