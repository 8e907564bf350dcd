//! Everything that changes while the world runs, in one place (as Rapier keeps
//! its bodies in sets): the school ([`World`]), each agent's motor and what
//! happened to it since its last decision, the colliders' axes, and the
//! clock. The stages (`physics`, `sensing`, `reward`, `chase`) read and write
//! this; the env's scratch buffers and outputs live elsewhere.

use crate::world::World;
use glam::{Mat3, Vec3};

/// Stages with fewer fish than this run as a single task (the parallel
/// passes of `crate::env` and `crate::physics` over the state's arrays).
pub const PAR_MIN_LEN: usize = 64;

/// Distinct collision partners remembered per decision; beyond, each contact counts anew.
pub(crate) const MAX_HITS: usize = 12;

/// What the current decision makes a fish do at each of its `k` physics steps (Eq. 4.4).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Motor {
    /// `Δv_f / k` (m/s): the policy's velocity change spread over the decision.
    pub dv_step: Vec3,
    /// `(Δv_light + Δv_temp)·BL / k` (m/s, positive up): the vertical
    /// responses computed at the decision, from the depth then, and spread over
    /// the decision as Eq. 4.4 (and Foids' Eq. 8) prescribe.
    pub vertical_step: f32,
    /// The speed clamp of this decision `[min, max]` (m/s), from the fish's
    /// [`crate::FishParams`] at the decision.
    pub speed_range: [f32; 2],
    /// With per-step actions (SPEC §4): the action acts at every physics step
    /// (`dv_step` is then unused).
    pub stepwise: bool,
    /// Per-step actions: speed change per physics step, `a0·Δv_max·BL·dt_sim` (m/s).
    pub accel_step: f32,
    /// Per-step actions: yaw `a2·θ_step` and pitch `a1·θ_step` per physics step (rad).
    pub yaw_step: f32,
    pub pitch_step: f32,
    /// A velocity change to apply at the next physics step (m/s): the contact
    /// kicks and pushes of SPEC §6.1.
    pub kick: Vec3,
}

/// Terms that accrue at every physics step (SPEC §6.1), summed since the decision.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Accrued {
    /// `r_M` summed over the steps.
    pub movement: f32,
    /// `r_BD` summed over the steps.
    pub boundary_distance: f32,
    /// `r_E` summed over the steps.
    pub energy: f32,
    /// Contacts that started (a partner not touched at the previous step).
    pub contact_starts: u32,
}

/// What happened to a fish since its last decision, and its episode counters.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Since {
    /// Its collider crossed a boundary (it has been respawned, or bounced back
    /// inside when the profile keeps the episode going).
    pub crossed: bool,
    /// As an aggressor, it touched its target.
    pub caught: bool,
    /// Neighbour contacts: the count, and the first [`MAX_HITS`] partners.
    pub n_hits: u8,
    pub hits: [u32; MAX_HITS],
    /// The partners of the previous decision (to count new collisions).
    pub n_prev: u8,
    pub prev: [u32; MAX_HITS],
    /// Heading at the decision (for the energy term's rotation).
    pub start_heading: Vec3,
    /// Respawns so far (keys the spawn stream); never reset.
    pub spawns: u32,
    /// Decisions in the current episode.
    pub episode_len: u32,
    /// Per-step terms accrued since the decision (SPEC §6.1).
    pub accrued: Accrued,
    /// The partners overlapping at the previous physics step (to find contact starts).
    pub n_touching: u8,
    pub touching: [u32; MAX_HITS],
}

impl Default for Since {
    fn default() -> Self {
        Self {
            crossed: false,
            caught: false,
            n_hits: 0,
            hits: [0; MAX_HITS],
            n_prev: 0,
            prev: [0; MAX_HITS],
            start_heading: Vec3::Z,
            spawns: 0,
            episode_len: 0,
            accrued: Accrued::default(),
            n_touching: 0,
            touching: [0; MAX_HITS],
        }
    }
}

impl Since {
    /// Note a contact with fish `j` (each partner once per decision).
    pub fn add_hit(&mut self, j: u32) {
        if self.hits[..(self.n_hits as usize).min(MAX_HITS)].contains(&j) {
            return;
        }
        if (self.n_hits as usize) < MAX_HITS {
            self.hits[self.n_hits as usize] = j;
        }
        self.n_hits = self.n_hits.saturating_add(1);
    }

    /// Partners not already touched during the previous decision.
    pub fn new_collisions(&self) -> u16 {
        let listed = (self.n_hits as usize).min(MAX_HITS);
        let prev = &self.prev[..(self.n_prev as usize).min(MAX_HITS)];
        let fresh = self.hits[..listed]
            .iter()
            .filter(|j| !prev.contains(j))
            .count();
        (fresh + (self.n_hits as usize - listed)) as u16
    }

    /// Start a new decision from the fish's current heading.
    pub fn start_decision(&mut self, heading: Vec3) {
        self.n_prev = self.n_hits.min(MAX_HITS as u8);
        self.prev = self.hits;
        self.n_hits = 0;
        self.crossed = false;
        self.caught = false;
        self.start_heading = heading;
        self.accrued = Accrued::default();
    }

    /// Whether fish `j` overlapped this one at the previous physics step.
    pub fn was_touching(&self, j: u32) -> bool {
        self.touching[..(self.n_touching as usize).min(MAX_HITS)].contains(&j)
    }
}

/// The world's changing state.
#[derive(Clone, Debug, Default)]
pub(crate) struct State {
    /// The school: identity and pose of every fish, chases, time.
    pub world: World,
    pub motor: Vec<Motor>,
    pub since: Vec<Since>,
    /// Each fish's collider axes after the latest physics step.
    pub axes: Vec<Mat3>,
    /// Ticks and physics steps since reset.
    pub tick: u64,
    pub physics_steps: u64,
    /// Light at the surface `I0(t)` (PAR), updated at every tick.
    pub surface_light: f32,
}

impl State {
    pub fn new(world: World) -> Self {
        let n = world.len();
        Self {
            world,
            motor: vec![Motor::default(); n],
            since: vec![Since::default(); n],
            axes: vec![Mat3::IDENTITY; n],
            tick: 0,
            physics_steps: 0,
            surface_light: 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Partners 3 and 5 touched last decision, 5 and 8 (twice) now: one new collision.
    #[test]
    fn new_collisions_skip_partners_of_the_previous_decision() {
        let mut s = Since::default();
        s.add_hit(3);
        s.add_hit(5);
        s.start_decision(Vec3::Z);
        s.add_hit(5);
        s.add_hit(8);
        s.add_hit(8);
        assert_eq!(s.n_hits, 2);
        assert_eq!(s.new_collisions(), 1);
    }
}
