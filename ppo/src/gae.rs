//! Generalised advantage estimation (Schulman et al. 2015) for one agent's
//! sequence of decisions, with the three ways a sequence can stop:
//!
//! * **terminated** — a true end: no bootstrap, `δ = r − V(s)`;
//! * **truncated** — an outside limit (the episode's maximum length): bootstrap
//!   from the next state's value, but do not carry the advantage across;
//! * **cut** — the time horizon (ML-Agents' `time_horizon`, 64): the trajectory
//!   is split there and bootstrapped exactly like a truncation.
//!
//! `δ_t = r_t + γ V(s_{t+1}) − V(s_t)`;
//! `A_t = δ_t + γ λ A_{t+1}` when the sequence continues, `A_t = δ_t` otherwise;
//! returns `R_t = A_t + V(s_t)`.

#[allow(clippy::too_many_arguments)]
/// Advantages and returns of a sequence of `rewards.len()` steps.
///
/// * `values[t]` is `V(s_t)`; `next_value` is `V(s_T)` after the last step;
/// * `stop[t]`: 0 continue, 1 truncated or cut (bootstrap, no carry), 2 terminated.
pub fn gae(
    rewards: &[f32],
    values: &[f32],
    next_value: f32,
    stop: &[u8],
    gamma: f32,
    lambda: f32,
    advantages: &mut [f32],
    returns: &mut [f32],
) {
    let n = rewards.len();
    let mut lastgaelam = 0.0f32;
    for t in (0..n).rev() {
        let next = if t + 1 < n { values[t + 1] } else { next_value };
        let (nextnonterminal, carry) = match stop[t] {
            0 => (1.0, 1.0),
            1 => (1.0, 0.0),
            _ => (0.0, 0.0),
        };
        let delta = rewards[t] + gamma * next * nextnonterminal - values[t];
        lastgaelam = delta + gamma * lambda * carry * lastgaelam;
        advantages[t] = lastgaelam;
        returns[t] = lastgaelam + values[t];
    }
}

/// Stop codes for [`gae`].
pub const CONTINUE: u8 = 0;
pub const BOOTSTRAP: u8 = 1;
pub const TERMINAL: u8 = 2;

#[cfg(test)]
mod tests {
    use super::*;

    /// The three steps below: rewards (1, 2, 3), values (0.5, 1, 1.5), V(s_3) = 2,
    /// γ = 0.9, λ = 0.5; returns (advantages, returns).
    fn three_steps(stops: [u8; 3]) -> ([f32; 3], [f32; 3]) {
        let (mut a, mut r) = ([0.0; 3], [0.0; 3]);
        gae(
            &[1.0, 2.0, 3.0],
            &[0.5, 1.0, 1.5],
            2.0,
            &stops,
            0.9,
            0.5,
            &mut a,
            &mut r,
        );
        (a, r)
    }

    /// γ = 0.9, λ = 0.5, three steps, rewards (1, 2, 3), values (0.5, 1, 1.5), V(s_3) = 2:
    /// δ_2 = 3 + 0.9·2 − 1.5 = 3.3;          A_2 = 3.3
    /// δ_1 = 2 + 0.9·1.5 − 1 = 2.35;         A_1 = 2.35 + 0.45·3.3 = 3.835
    /// δ_0 = 1 + 0.9·1 − 0.5 = 1.4;          A_0 = 1.4 + 0.45·3.835 = 3.12575
    #[test]
    fn continuing_sequence() {
        let (a, r) = three_steps([0, 0, 0]);
        for (x, y) in a.iter().zip([3.125_75, 3.835, 3.3]) {
            assert!((x - y).abs() < 1e-5, "{a:?}");
        }
        assert!((r[0] - 3.625_75).abs() < 1e-5);
    }

    /// Terminated at step 1: δ_1 = 2 − 1 = 1 (no bootstrap), A_1 = 1; step 2 starts afresh:
    /// A_2 = 3.3; A_0 = 1.4 + 0.45·1 = 1.85.
    #[test]
    fn termination_stops_bootstrap_and_carry() {
        let (a, _) = three_steps([0, TERMINAL, 0]);
        for (x, y) in a.iter().zip([1.85, 1.0, 3.3]) {
            assert!((x - y).abs() < 1e-5, "{a:?}");
        }
    }

    /// Truncated (or cut) at step 1: δ_1 bootstraps from V(s_2) = 1.5 — 2.35 as before — but
    /// does not carry A_2: A_1 = 2.35, A_0 = 1.4 + 0.45·2.35 = 2.4575.
    #[test]
    fn truncation_bootstraps_without_carry() {
        let (a, _) = three_steps([0, BOOTSTRAP, 0]);
        for (x, y) in a.iter().zip([2.4575, 2.35, 3.3]) {
            assert!((x - y).abs() < 1e-5, "{a:?}");
        }
    }
}
