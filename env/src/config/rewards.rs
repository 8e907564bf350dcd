//! Reward-profile files, `rewards/<profile>/<phase>.toml`: [`RewardWeights`]
//! with the profile's [`Timing`], [`Contacts`] and [`Extensions`], and the
//! [`Phase`] that picks the file.

use super::check::{BL, SPEED, WEIGHT, check, check_count};
use super::error::ConfigError;
use crate::limits::{MAX_FISH, MAX_NEIGHBOUR_CAP};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The training phase, which picks the reward weights (thesis §4.5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    #[default]
    Pretrain,
    Transfer,
}

impl Phase {
    pub fn as_str(&self) -> &'static str {
        match self {
            Phase::Pretrain => "pretrain",
            Phase::Transfer => "transfer",
        }
    }
}

impl std::str::FromStr for Phase {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "pretrain" => Ok(Phase::Pretrain),
            "transfer" => Ok(Phase::Transfer),
            _ => Err(format!("unknown phase `{s}`; allowed: pretrain, transfer")),
        }
    }
}

/// When the action acts (SPEC §4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ActionTiming {
    /// The original Unity agent's reading: at every physics step the speed
    /// changes by `a0 · Δv_max · BL · dt_sim` (`Δv_max` in BL/s per second) and
    /// the heading turns by `a1, a2 · turn_step_deg` (SPEC §4; the default).
    #[default]
    PerStep,
    /// The earlier reading: the whole change of one decision (`a0 · Δv_max`
    /// BL/s, `θ_max` = `physics.max_turn_deg` per decision) spread over its k steps.
    PerDecision,
}

/// When `r_M`, `r_BD`, `r_E` and `r_NC` accrue (SPEC §6.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum RewardTiming {
    /// `r_M`, `r_BD` and `r_E` at every physics step, `r_NC` once when a
    /// contact starts, `r_ND` and `r_C` once per decision (SPEC §6.1; the default).
    #[default]
    PerStep,
    /// Every term once per decision from the state at the decision; `r_NC`
    /// per distinct partner touched during the decision (the earlier reading).
    PerDecision,
}

/// When the action acts and the rewards accrue (SPEC §4, §6.1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Timing {
    /// SPEC §4: `per_step` (default) or `per_decision`.
    pub actions: ActionTiming,
    /// SPEC §6.1: `per_step` (default) or `per_decision`.
    pub rewards: RewardTiming,
    /// Heading change per physics step at a full action, `θ_step` (degrees),
    /// with `actions = "per_step"`. SPEC §4: 1 (the original's Euler angle per step).
    pub turn_step_deg: f32,
}

impl Default for Timing {
    fn default() -> Self {
        Self {
            actions: ActionTiming::PerStep,
            rewards: RewardTiming::PerStep,
            turn_step_deg: 1.0,
        }
    }
}

/// Fish–fish contacts (SPEC §6.1): the repulsive velocity kicks of the
/// original agent. Both in m/s, not BL-scaled, as the Unity agent sets them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Contacts {
    /// Velocity kick away from the partner on the step a contact starts (m/s).
    /// The Unity agent: 0.03 for 1,000 coho, 0.05 for 300. Default 0.03.
    pub kick: f32,
    /// Velocity push away from the partner at every step while they overlap (m/s).
    /// The Unity agent: 0.0003. Default 0.0003.
    pub push: f32,
}

impl Default for Contacts {
    fn default() -> Self {
        Self {
            kick: 0.03,
            push: 0.0003,
        }
    }
}

/// How `r_ND` counts neighbours (SPEC §6, §6.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum NeighbourForm {
    /// `Σ_j (90 − Δθ_j)/90`, the thesis' sum (default).
    #[default]
    Sum,
    /// The same sum divided by the number of neighbours counted (§6.2: normalised).
    Mean,
    /// The same sum divided by the square root of the number counted: between the
    /// two, it still grows with density (×√n for n aligned neighbours, where the
    /// sum grows ×n and the mean not at all).
    Sqrt,
}

/// How `r_ND` weighs a neighbour by its distance (SPEC §6.2; ours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum NeighbourWeight {
    /// Every neighbour within `d_sense` alike: the thesis' sum (default).
    #[default]
    Even,
    /// A neighbour `d` away weighs `4 · (1 − d / d_sense)`: the nearest count
    /// most, one at the edge of the range nothing, and neighbours spread evenly
    /// through the sensing sphere weigh 1 on average (the mean of `1 − r/R`
    /// over a ball is 1/4), so an even school earns what the sum pays. A
    /// school touches as often as fish that ignore each other unless the
    /// nearest neighbours swim parallel (NOTES, session 52), and the sum over
    /// up to 90 of them hardly pays for that. Not in the sources.
    Proximity,
}

/// Whose body length SPEC §6.2's personal space is measured in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum PersonalSpaceOf {
    /// The fish's own (default): a large fish keeps a large fish's distance from
    /// a small one that does not keep it back.
    #[default]
    Own,
    /// The mean of the two fish's: symmetric, so both of a pair agree whether
    /// they are too close (as a contact is for both). The same as `own` where
    /// every fish has one size; it differs in mixed sizes (`coho_mixed`).
    Pair,
}

/// How long a fish keeps the handedness `mirrored_share` draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MirrorRedraw {
    /// For its life: exactly `round(share · n)` fish of a behaviour, drawn
    /// when the env is built (default).
    #[default]
    Life,
    /// Anew at every decision, each fish mirrored with probability `share`
    /// (its older stacked frames mirrored to match): a policy's turning bias
    /// then acts either way at random, so what the school does comes from
    /// what the fish see, as under a policy that is its own mirror image.
    Decision,
}

/// Whose heading the vector observation's `u` gives (SPEC §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum HeadingOf {
    /// The nearest neighbour in front (SPEC §5; default).
    #[default]
    Front,
    /// The neighbour within `d_sense` that will come closest within the next
    /// [`crate::sensing::CLOSING_HORIZON_S`] seconds if both keep their
    /// velocities (the least distance of closest approach, ties to the nearer
    /// now): the one a collision is coming from. Not in the sources.
    Closing,
    /// The mean heading (normalised) of the neighbours `r_ND` is paid for:
    /// the `neighbour_cap` nearest outside the personal space (all within
    /// `d_sense` when uncapped), conspecifics only with `conspecific_only`.
    /// The fish is shown the headings its alignment reward is computed from;
    /// `u` is zero when there are none. Not in the sources.
    Rewarded,
}

impl HeadingOf {
    /// As the profile files write it.
    pub fn as_str(&self) -> &'static str {
        match self {
            HeadingOf::Front => "front",
            HeadingOf::Closing => "closing",
            HeadingOf::Rewarded => "rewarded",
        }
    }
}

/// The extensions of SPEC §6.2 the thesis cites but never formalises; all off by default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Extensions {
    /// `r_ND` as the thesis' `sum` (default), the `mean` over the neighbours counted,
    /// or the sum over `sqrt` of their number.
    pub neighbour_form: NeighbourForm,
    /// Each neighbour's `r_ND` term `even`ly (the thesis', default) or by its
    /// `proximity` ([`NeighbourWeight`]).
    pub neighbour_weight: NeighbourWeight,
    /// Personal space (Føre et al. 2009: ≥ 0.66 BL) in BL: a neighbour nearer
    /// than this does not count for `r_ND`. 0 (default): off.
    pub personal_space_bl: f32,
    /// Whose body length `personal_space_bl` counts in: `own` (default) or the
    /// `pair`'s mean.
    pub personal_space_of: PersonalSpaceOf,
    /// The personal space stretched along the lane ahead, in BL: a neighbour
    /// in front of the fish (its offset along the heading `a > 0`, off it `l`)
    /// is inside when `(a / ahead)² + (l / personal_space_bl)² < 1`; behind or
    /// beside, the sphere of `personal_space_bl` as before. A contact is an
    /// overlap of 1 BL long colliders, so a follower in a neighbour's lane
    /// touches it at any distance under 1 BL, where the sphere of 0.66 BL does
    /// not see it (NOTES, session 47). Not in the sources: a profile switch.
    /// 0 (default): off, the sphere.
    pub personal_space_ahead_bl: f32,
    /// Misalignment inside the personal space: a neighbour inside costs
    /// `personal_space_penalty · (1 + m · (1 − (90 − Δθ)/90))`, so a parallel
    /// one the penalty, one crossing at 90° `1 + m` times it, a head-on one
    /// `1 + 2m` times (r_ND's alignment term, which does not count a
    /// neighbour inside; most contacts are paths crossing at ≈ 45°, NOTES,
    /// session 49). Not in the sources: a profile switch. 0 (default): off.
    pub personal_space_misalignment: f32,
    /// Penalty per neighbour inside the personal space, per decision, added to
    /// `r_ND` (> 0 means a cost). 0 (default): none.
    pub personal_space_penalty: f32,
    /// A budget of neighbours for `r_ND`'s sum: with more than this many
    /// counted, the sum is scaled by `budget / counted`, so packing past the
    /// neighbours an even spread would bring within `d_sense` earns nothing more
    /// (the mean alignment still pays; SPEC §6.2, a normalised r_ND). 0
    /// (default): no budget. Only the `sum` form uses it.
    pub neighbour_budget: u32,
    /// A quorum for `r_ND`'s alignment pay: a fish with fewer than this many
    /// neighbours that `r_ND` would count (within `d_sense`, outside the
    /// personal space, of its species when `conspecific_only`; counted before
    /// `neighbour_cap`) earns no alignment pay at that decision; the personal
    /// space's price still applies. Quorum responses in shoals: Ward et al.
    /// 2008, Sumpter et al. 2008; an ordered school forming at a critical
    /// density: Makris et al. 2009. The number itself is not in the sources:
    /// a tuning device (NOTES, session 62). 0 (default): off.
    pub neighbour_quorum: u32,
    /// Assortment (Krause et al. 1996): `r_ND` counts only neighbours of the
    /// fish's own species. Default false.
    pub conspecific_only: bool,
    /// Assortment by size: each neighbour's `r_ND` term is weighted by
    /// `min(BL_i, BL_j) / max(BL_i, BL_j)`. Default false.
    pub size_weighted: bool,
    /// Whether a net, bottom or surface collision ends the agent's episode
    /// (SPEC §6, default true). With false the fish pays `r_BC`, bounces back
    /// inside (the velocity reflected off the plane, the collider moved back
    /// inside) and its episode goes on (SPEC §6.2).
    pub boundary_ends_episode: bool,
    /// Whose heading the vector observation carries: the nearest neighbour
    /// `front` (SPEC §5, default) or the `closing` one. Six contacts in ten
    /// are paths crossing at ≈ 45° (NOTES, session 49), and the grid shows
    /// where a neighbour is, not where it heads. It changes what the policy
    /// sees, so a profile sets it in both phases (checked). Not in the sources.
    pub heading_of: HeadingOf,
    /// The share of each behaviour's fish that act as the mirror image of the
    /// policy: they see their grid with the azimuth columns reversed and the
    /// lateral component of `u` negated, and their yaw action is negated, so
    /// a policy that prefers one turn makes them prefer the other. A shared
    /// policy otherwise gives a whole school one handedness, which no
    /// population of real fish has (lateralisation is individual). Exactly
    /// `round(share · n)` fish of a behaviour, drawn from the seed, for their
    /// whole life unless `mirror_redraw` says otherwise. Only policies that act on the observations are mirrored
    /// (not the rule-based baselines). Not in the sources. 0 (default): none.
    pub mirrored_share: f32,
    /// Whether a fish keeps its handedness for `life` (default) or draws it
    /// anew at every `decision` ([`MirrorRedraw`]).
    pub mirror_redraw: MirrorRedraw,
}

impl Default for Extensions {
    fn default() -> Self {
        Self {
            neighbour_form: NeighbourForm::Sum,
            neighbour_weight: NeighbourWeight::Even,
            personal_space_bl: 0.0,
            personal_space_of: PersonalSpaceOf::Own,
            personal_space_ahead_bl: 0.0,
            personal_space_misalignment: 0.0,
            personal_space_penalty: 0.0,
            neighbour_budget: 0,
            neighbour_quorum: 0,
            conspecific_only: false,
            size_weighted: false,
            boundary_ends_episode: true,
            heading_of: HeadingOf::Front,
            mirrored_share: 0.0,
            mirror_redraw: MirrorRedraw::Life,
        }
    }
}

/// Reward weights of one phase of a reward profile (SPEC §6, Table 4.1), with
/// the profile's timing (§4, §6.1), contacts (§6.1) and extensions (§6.2).
/// File: `rewards/<profile>/<phase>.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RewardWeights {
    /// Penalty of a boundary collision, `−r_BC` (> 0). SPEC §6: 300.
    pub boundary_collision: f32,
    /// Neighbour collision weight `w_NC`. Pretrain 0.5, transfer 4.
    pub w_nc: f32,
    /// Boundary avoidance weight `w_BD`. 2.
    pub w_bd: f32,
    /// Neighbour interaction weight `w_ND`. 1.5.
    pub w_nd: f32,
    /// `r_ND` sums over at most this many nearest neighbours within `d_sense`
    /// (0: every one, as SPEC §6 writes it). A topological cap keeps the
    /// reward's scale independent of density (issue 14; README deviations).
    #[serde(default)]
    pub neighbour_cap: u32,
    /// Rotation penalty weight `w_r` (per degree). Pretrain 0.001, transfer 0.5.
    pub w_r: f32,
    /// Speed-change penalty weight `w_s` (per BL/s). Pretrain 5, transfer 10.
    pub w_s: f32,
    /// Penalty for a pitch at or beyond `θrt` (> 0). SPEC §6: 10.
    pub pitch_penalty: f32,
    /// Bonus for level swimming at or above `v_st`. SPEC §6: 2.
    pub movement_bonus: f32,
    /// Chase reward weight of the aggressor `w_agg` (per BL/s). 8.
    pub w_agg: f32,
    /// Escape weight of the target `w_tar` (per BL/s). 1.
    pub w_tar: f32,
    /// One-off reward of an aggressor hitting its target. SPEC §6: 100.
    pub catch_bonus: f32,
    /// When actions act and terms accrue (SPEC §4, §6.1).
    #[serde(default)]
    pub timing: Timing,
    /// Contact kicks (SPEC §6.1).
    #[serde(default)]
    pub contacts: Contacts,
    /// SPEC §6.2's extensions (all off by default).
    #[serde(default)]
    pub extensions: Extensions,
}

impl RewardWeights {
    /// The bounds of a reward-weights file.
    pub(crate) fn check_bounds(&self, path: &Path) -> Result<(), ConfigError> {
        let r = self;
        let fields = [
            ("boundary_collision", r.boundary_collision),
            ("w_nc", r.w_nc),
            ("w_bd", r.w_bd),
            ("w_nd", r.w_nd),
            ("w_r", r.w_r),
            ("w_s", r.w_s),
            ("pitch_penalty", r.pitch_penalty),
            ("movement_bonus", r.movement_bonus),
            ("w_agg", r.w_agg),
            ("w_tar", r.w_tar),
            ("catch_bonus", r.catch_bonus),
            (
                "extensions.personal_space_penalty",
                r.extensions.personal_space_penalty,
            ),
            (
                "extensions.personal_space_misalignment",
                r.extensions.personal_space_misalignment,
            ),
        ];
        for (field, v) in fields {
            check(path, field, v, WEIGHT, "")?;
        }
        let cap = MAX_NEIGHBOUR_CAP;
        check_count(
            path,
            "neighbour_cap",
            r.neighbour_cap as u64,
            cap as u64,
            "neighbours (0: every neighbour)",
        )?;
        check_count(
            path,
            "extensions.neighbour_budget",
            r.extensions.neighbour_budget as u64,
            MAX_FISH as u64,
            "neighbours (0: no budget)",
        )?;
        check_count(
            path,
            "extensions.neighbour_quorum",
            r.extensions.neighbour_quorum as u64,
            MAX_FISH as u64,
            "neighbours (0: off)",
        )?;
        check(
            path,
            "timing.turn_step_deg",
            r.timing.turn_step_deg,
            [0.0, 90.0],
            "°",
        )?;
        check(path, "contacts.kick", r.contacts.kick, SPEED, "m/s")?;
        check(path, "contacts.push", r.contacts.push, SPEED, "m/s")?;
        let x = &r.extensions;
        check(
            path,
            "extensions.personal_space_bl",
            x.personal_space_bl,
            BL,
            "BL",
        )?;
        check(
            path,
            "extensions.personal_space_ahead_bl",
            x.personal_space_ahead_bl,
            BL,
            "BL",
        )?;
        check(
            path,
            "extensions.mirrored_share",
            x.mirrored_share,
            [0.0, 1.0],
            "",
        )?;
        if x.personal_space_ahead_bl > 0.0 && x.personal_space_bl <= 0.0 {
            return Err(ConfigError::Invalid {
                path: path.to_path_buf(),
                field: "extensions.personal_space_ahead_bl".into(),
                message: format!(
                    "{} stretches a personal space that is off: set \
                     extensions.personal_space_bl > 0 too, or this to 0",
                    x.personal_space_ahead_bl
                ),
            });
        }
        Ok(())
    }
}
