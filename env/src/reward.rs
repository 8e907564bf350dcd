//! The reward stage (SPEC §6; thesis §4.1.4, Eq. 4.5, Table 4.1).
//!
//! Per decision, looking back on the `k` physics steps since the previous one:
//! `r = r_BC + r_NC + r_BD + r_ND + r_E + r_M + r_C` ([`Terms::total`]).
//! Each term is a function of its own below, with its definition.
//!
//! When each term accrues is the profile's `timing.rewards` (SPEC §6.1):
//! * `per_step` (default, the Unity agent's): `r_M`, `r_BD` and `r_E` are
//!   summed over the decision's physics steps (the physics stage accrues them,
//!   [`crate::state::Accrued`]); `r_NC` is `−w_NC` per contact that *started*
//!   (a partner not overlapping at the previous step), so a lasting contact
//!   pays once; `r_ND` and `r_C` come once, from the state at the decision.
//! * `per_decision` (the earlier reading): every term once, from the state at
//!   the decision; `r_NC` per distinct partner touched during the decision.
//!
//! A fish whose collider crossed a boundary earns `r_BC` (and, per step, what
//! accrued before the crossing, and its contacts); if the crossing ends the
//! episode (the default) it earns nothing else (its end state lies outside the
//! cage; *terminated*). With `boundary_ends_episode = false` it bounced back
//! inside and earns every term besides. Reaching `max_episode_decisions`
//! *truncates* the episode.

use crate::config::{RewardTiming, RewardWeights};
use crate::kinematics::{angle_deg, pitch_deg};
use crate::sensing::Surroundings;
use crate::state::{Motor, Since};
use crate::world::{Chase, World};
use glam::Vec3;

/// Number of reward terms.
pub const N_TERMS: usize = 7;
/// Names of the reward terms, in the order of [`crate::BehaviourBatch::terms`] (Eq. 4.5).
pub const TERM_NAMES: [&str; N_TERMS] = [
    "boundary_collision",
    "neighbour_collision",
    "boundary_distance",
    "neighbour_distance",
    "energy",
    "movement",
    "chase",
];

/// The thesis' symbols of the terms, in the order of [`TERM_NAMES`].
pub const TERM_SYMBOLS: [&str; N_TERMS] = ["r_BC", "r_NC", "r_BD", "r_ND", "r_E", "r_M", "r_C"];

/// The seven terms of one decision's reward.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Terms {
    /// `r_BC`.
    pub boundary_collision: f32,
    /// `r_NC`.
    pub neighbour_collision: f32,
    /// `r_BD`.
    pub boundary_distance: f32,
    /// `r_ND`.
    pub neighbour_distance: f32,
    /// `r_E`.
    pub energy: f32,
    /// `r_M`.
    pub movement: f32,
    /// `r_C`.
    pub chase: f32,
}

impl Terms {
    /// The terms in the order of [`TERM_NAMES`].
    pub fn to_array(&self) -> [f32; N_TERMS] {
        [
            self.boundary_collision,
            self.neighbour_collision,
            self.boundary_distance,
            self.neighbour_distance,
            self.energy,
            self.movement,
            self.chase,
        ]
    }

    /// Eq. 4.5: `r = r_BC + r_NC + r_BD + r_ND + r_E + r_M + r_C` (summed in that order).
    pub fn total(&self) -> f32 {
        self.to_array().iter().sum()
    }
}

/// `r_BC = −300` for a boundary collision (the weight's sign flipped), else 0.
pub fn boundary_collision(w: &RewardWeights, crossed: bool) -> f32 {
    if crossed { -w.boundary_collision } else { 0.0 }
}

/// `r_NC = −w_NC · N_hit`, `N_hit` the fish touched since the last decision.
pub fn neighbour_collision(w: &RewardWeights, n_hit: u32) -> f32 {
    -w.w_nc * n_hit as f32
}

/// `r_BD = −w_BD · Σ_i (d_sense − d_i)/d_sense` over boundaries within `d_sense`
/// (`closeness` is the sum).
pub fn boundary_distance(w: &RewardWeights, closeness: f32) -> f32 {
    -w.w_bd * closeness
}

/// `r_ND = w_ND · Σ_j (90 − Δθ_j)/90` over neighbours within `d_sense`
/// (`alignment` is the sum; `Δθ_j` in degrees), less SPEC §6.2's personal-space
/// penalty per neighbour inside it (`crowding`: their number, or with
/// `personal_space_misalignment` their weighted sum).
pub fn neighbour_distance(w: &RewardWeights, alignment: f32, crowding: f32) -> f32 {
    w.w_nd * alignment - w.extensions.personal_space_penalty * crowding
}

/// `r_E = −w_r · Δθ − w_s · |Δv_a|`: `Δθ` the body's rotation over the
/// decision (degrees); `Δv_a` the velocity change the fish applies at each
/// physics step of the decision, Eq. 4.4's `Δv_f/k + (Δv_light + Δv_temp)/k`
/// (BL/s; "the delta accumulated speed at the current time step" — the
/// thesis' Δv_a is Eq. 4.4's per-step vector; README, SPEC deviations).
pub fn energy(w: &RewardWeights, turned_deg: f32, dv_a_bl: f32) -> f32 {
    -w.w_r * turned_deg - w.w_s * dv_a_bl.abs()
}

/// `r_M`: `−10` if the pitch magnitude is at least `θrt` (53°); `+2` if it is
/// below and the speed is at least `v_st` (0.3 BL/s); else 0.
pub fn movement(
    w: &RewardWeights,
    pitch_deg: f32,
    speed_bl: f32,
    pitch_threshold_deg: f32,
    speed_threshold_bl: f32,
) -> f32 {
    if pitch_deg.abs() >= pitch_threshold_deg {
        -w.pitch_penalty
    } else if speed_bl >= speed_threshold_bl {
        w.movement_bonus
    } else {
        0.0
    }
}

/// `r_C`: an aggressor earns `w_agg · (d̂ · v_a)` (`d̂` towards its target,
/// `v_a` its velocity in BL/s), or `+100` once when it has touched its target;
/// a target earns `−w_tar · (d̂_t · v_a)` (`d̂_t` towards its aggressor); 0 otherwise.
pub fn chase(w: &RewardWeights, world: &World, i: usize, caught: bool) -> f32 {
    let towards = |j: u32| (world.position[j as usize] - world.position[i]).normalize_or_zero();
    let v_bl: Vec3 = world.velocity(i) / world.bl[i];
    match world.chase[i] {
        Chase::Aggressor { .. } if caught => w.catch_bonus,
        Chase::Aggressor { target, .. } => w.w_agg * towards(target).dot(v_bl),
        Chase::Target { aggressor } => -w.w_tar * towards(aggressor).dot(v_bl),
        Chase::None => 0.0,
    }
}

/// What a decision brought one fish (before the chase update).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Outcome {
    pub terms: Terms,
    /// The fish's collider crossed a boundary (terminated, or bounced back).
    pub crossed: bool,
    pub terminated: bool,
    pub truncated: bool,
    pub new_collisions: u16,
    pub nearest_subordinate: Option<u32>,
}

/// Read-only view of what the reward needs.
pub(crate) struct Rewards<'a> {
    pub world: &'a World,
    pub since: &'a [Since],
    /// Each fish's motor of the decision just ended (Eq. 4.4's per-step changes).
    pub motor: &'a [Motor],
    pub weights: &'a RewardWeights,
    pub pitch_threshold_deg: f32,
    pub speed_threshold_bl: f32,
    pub max_episode: u32,
}

impl Rewards<'_> {
    /// The terms, episode end and new collisions of fish `i` for the decision just ended.
    pub fn evaluate(&self, i: usize, seen: &Surroundings) -> Outcome {
        let (w, rw, since) = (self.world, self.weights, &self.since[i]);
        let bl = w.bl[i];
        let per_step = rw.timing.rewards == RewardTiming::PerStep;
        let terminated = since.crossed && rw.extensions.boundary_ends_episode;
        let contacts = if per_step {
            since.accrued.contact_starts
        } else {
            since.n_hits as u32
        };
        let mut terms = Terms {
            boundary_collision: boundary_collision(rw, since.crossed),
            neighbour_collision: neighbour_collision(rw, contacts),
            ..Terms::default()
        };
        if per_step {
            terms.boundary_distance = since.accrued.boundary_distance;
            terms.energy = since.accrued.energy;
            terms.movement = since.accrued.movement;
        }
        if !terminated {
            terms.neighbour_distance = neighbour_distance(rw, seen.alignment_sum, seen.crowding);
            terms.chase = chase(rw, w, i, since.caught);
        }
        if !terminated && !per_step {
            terms.boundary_distance = boundary_distance(rw, seen.boundary_sum);
            let m = &self.motor[i];
            let dv_a = m.dv_step + Vec3::new(0.0, m.vertical_step, 0.0);
            terms.energy = energy(
                rw,
                angle_deg(since.start_heading, w.heading[i]),
                dv_a.length() / bl,
            );
            terms.movement = movement(
                rw,
                pitch_deg(w.heading[i]),
                w.speed[i] / bl,
                self.pitch_threshold_deg,
                self.speed_threshold_bl,
            );
        }
        Outcome {
            terms,
            crossed: since.crossed,
            terminated,
            truncated: !terminated && since.episode_len + 1 >= self.max_episode,
            new_collisions: since.new_collisions(),
            nearest_subordinate: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pretrain() -> RewardWeights {
        RewardWeights {
            boundary_collision: 300.0,
            w_nc: 0.5,
            w_bd: 2.0,
            w_nd: 1.5,
            neighbour_cap: 0,
            w_r: 0.001,
            w_s: 5.0,
            pitch_penalty: 10.0,
            movement_bonus: 2.0,
            w_agg: 8.0,
            w_tar: 1.0,
            catch_bonus: 100.0,
            timing: Default::default(),
            contacts: Default::default(),
            extensions: Default::default(),
        }
    }

    /// Hand-computed with the pretraining weights: 3 partners → −1.5; closeness
    /// 0.25 → −0.5; alignment 1.5 → +2.25; a 10° turn and a per-step velocity
    /// change of 0.2 BL/s → −0.01 − 1 = −1.01; level at 0.5 BL/s → +2; no
    /// chase. Eq. 4.5: 1.24.
    #[test]
    fn terms_and_their_sum() {
        let w = pretrain();
        let t = Terms {
            boundary_collision: boundary_collision(&w, false),
            neighbour_collision: neighbour_collision(&w, 3),
            boundary_distance: boundary_distance(&w, 0.25),
            neighbour_distance: neighbour_distance(&w, 1.5, 0.0),
            energy: energy(&w, 10.0, -0.2),
            movement: movement(&w, 5.0, 0.5, 53.0, 0.3),
            chase: 0.0,
        };
        assert_eq!(t.to_array(), [0.0, -1.5, -0.5, 2.25, -1.01, 2.0, 0.0]);
        assert!((t.total() - 1.24).abs() < 1e-6, "{}", t.total());
        assert_eq!(boundary_collision(&w, true), -300.0);
    }

    /// r_M: pitch −53° → −10 (whatever the speed); 52.9° at 0.3 BL/s → +2; level at 0.29 → 0.
    #[test]
    fn movement_thresholds() {
        let w = pretrain();
        assert_eq!(movement(&w, -53.0, 1.0, 53.0, 0.3), -10.0);
        assert_eq!(movement(&w, 52.9, 0.3, 53.0, 0.3), 2.0);
        assert_eq!(movement(&w, 0.0, 0.29, 53.0, 0.3), 0.0);
    }
}
