//! Who the fish are: per-behaviour constants, each fish's traits drawn from the
//! seed when the env is built (SPEC §2), and the parameters of the model that
//! moves each fish ([`FishParams`]).
//!
//! * Drawn per fish from `(seed, Traits, fish)`: the body scale (so the body
//!   length `BL`), the light preferences `[I_lpref, I_hpref]` (an `I_hpref`
//!   below `I_lpref` is reset to the midpoint of its range, the Foids rule);
//!   from `(seed, Dominance, behaviour)`: exactly `round(0.2·n)` dominant fish
//!   of each behaviour. These live in the public [`World`] (`bl`,
//!   `light_pref`, `dominant`, `behaviour`, `species`). From
//!   `(seed, Handedness, behaviour)`: exactly `round(mirrored_share · n)`
//!   mirrored fish of each behaviour (the reward profile's extension).
//! * Derived from the species and `BL`, fixed: the box collider's half extents
//!   and bounding radius, the visual radius the grid sensor sees, the sensing
//!   range `d_sense` — here, in `Traits`.
//! * [`FishParams`]: the speed range (SPEC §4: the species' schooling range
//!   `speed_bl`, whose lower bound is a floor) and the light steepness of
//!   Eq. 4.2. They default to the species' values for every fish whoever acts;
//!   a rule-based model with its own published values (Foids: night speeds,
//!   hovering, Table 1's light steepness) sets them through
//!   [`crate::Policy::fish_params`].

use crate::config::Range;
use crate::rng::{Purpose, Stream};
use crate::scene::Scene;
use crate::world::{Chase, World};
use glam::Vec3;

/// Per-behaviour constants, in SI units where the spec gives BL.
#[derive(Clone, Debug)]
pub struct BehaviourInfo {
    pub name: String,
    pub species: String,
    pub size_class: String,
    /// The behaviour's fish are `first..first + count`.
    pub first: usize,
    pub count: usize,
    /// Physics steps per decision `k`.
    pub steps_per_decision: usize,
    /// Ticks per decision.
    pub period_ticks: u64,
    pub(crate) max_delta_speed_bl: f32,
    pub(crate) v0_bl: f32,
    pub(crate) sense_bl: f32,
    pub(crate) collider_bl: Vec3,
    pub(crate) temperature_pref: [f32; 2],
    pub(crate) temperature_steep: [f32; 2],
    /// The species' defaults of [`FishParams`].
    pub(crate) params: FishParams,
}

impl BehaviourInfo {
    /// Fish indices of this behaviour.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.count
    }
}

/// Parameters of the model that moves a fish, which a rule-based baseline may
/// set to its own published values (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FishParams {
    /// Speed range `[min, max]` (BL/s): the clamp of every decision's target
    /// speed and of every physics step (SPEC §4). Default: the species'
    /// schooling range (Table 4.3), e.g. coho `[0.2, 1.9]`.
    pub speed_bl: [f32; 2],
    /// Light steepness `[I_lsteep, I_hsteep]` (PAR) of Eq. 4.2. Default: the
    /// species' (SPEC §2: `[−20, 1000]`).
    pub light_steep: [f32; 2],
}

impl FishParams {
    /// Whether the values make sense: a finite speed range `0 ≤ min ≤ max`,
    /// `max > 0`, and steepness `[negative, positive]`; else what is wrong.
    pub fn check(&self) -> Result<(), String> {
        let [lo, hi] = self.speed_bl;
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi && hi > 0.0) {
            return Err(format!(
                "speed_bl {:?} must be finite with 0 ≤ min ≤ max and max > 0",
                self.speed_bl
            ));
        }
        let [ls, hs] = self.light_steep;
        if !(ls.is_finite() && hs.is_finite() && ls < 0.0 && hs > 0.0) {
            return Err(format!(
                "light_steep {:?} must be [negative, positive] and finite",
                self.light_steep
            ));
        }
        Ok(())
    }
}

/// Per-fish constants derived from the species and the body length, and the
/// current [`FishParams`] of each fish (structure of arrays, indexed by fish).
#[derive(Clone, Debug, Default)]
pub(crate) struct Traits {
    /// Collider half extents (m).
    pub half: Vec<Vec3>,
    /// Collider bounding radius (m).
    pub bound: Vec<f32>,
    /// The largest bounding radius (m).
    pub max_bound: f32,
    /// Radius the grid sensor sees the fish as (m).
    pub visual: Vec<f32>,
    /// Sensing range `d_sense` (m).
    pub sense: Vec<f32>,
    /// The model's parameters for each fish (BL units, see [`FishParams`]).
    pub params: Vec<FishParams>,
    /// Whether the fish acts as the policy's mirror image (the profile's
    /// `mirrored_share`): its grid's azimuth columns reversed, `u_x` and its
    /// yaw action negated.
    pub mirrored: Vec<bool>,
    /// Whether the mirrored fish act mirrored: off while a rule-based
    /// baseline, which steers from the world and not from the observations,
    /// drives the env ([`crate::Env::set_mirroring`]).
    pub mirroring: bool,
}

impl Traits {
    /// Whether fish `i` sees and steers as the policy's mirror image now.
    #[inline]
    pub fn is_mirrored(&self, i: usize) -> bool {
        self.mirroring && self.mirrored[i]
    }
}

/// Draw the school of `scene` from `seed`: the behaviours' constants, each
/// fish's identity in a [`World`] (at the origin; [`crate::Env::reset`] places
/// it), and the derived [`Traits`].
pub(crate) fn draw(scene: &Scene, seed: u64) -> (Vec<BehaviourInfo>, World, Traits) {
    let dt = scene.physics.dt_sim;
    let species_names = scene.species_names();
    let mut info = Vec::new();
    let mut world = World::default();
    let mut mirrored = Vec::new();
    let mut first = 0;
    for (b, spec) in scene.behaviours.iter().enumerate() {
        let sp = &spec.species;
        info.push(BehaviourInfo {
            name: spec.name.clone(),
            species: sp.name.clone(),
            size_class: spec.size_class.clone(),
            first,
            count: spec.count,
            steps_per_decision: spec.steps_per_decision(dt),
            period_ticks: 0,
            max_delta_speed_bl: sp.max_delta_speed_bl,
            v0_bl: sp.initial_speed_bl,
            sense_bl: sp.sense_range_bl,
            collider_bl: Vec3::from(sp.collider_bl),
            temperature_pref: sp.temperature_pref,
            temperature_steep: sp.temperature_steep,
            params: FishParams {
                speed_bl: sp.speed_bl,
                light_steep: sp.light_steep,
            },
        });
        let species_idx = species_names
            .iter()
            .position(|s| *s == sp.name)
            .unwrap_or(0) as u16;
        let mut group_scales = spec
            .body_scales
            .iter()
            .flat_map(|(n, r)| std::iter::repeat_n(*r, *n));
        for i in first..first + spec.count {
            let mut s = Stream::new(seed, Purpose::Traits, i as u64, 0);
            let scale: Range = group_scales.next().unwrap_or(Range::Fixed(1.0));
            let bl = sp.body_length * scale.at(s.uniform());
            let lpref = spec.light_lpref.at(s.uniform());
            let mut hpref = spec.light_hpref.at(s.uniform());
            if hpref < lpref {
                hpref = spec.light_hpref.midpoint();
            }
            world.behaviour.push(b as u16);
            world.species.push(species_idx);
            world.bl.push(bl);
            world.light_pref.push([lpref, hpref]);
        }
        // Dominance: exactly round(fraction · n) fish of the behaviour.
        let n_dom = (sp.dominant_fraction * spec.count as f32).round() as usize;
        world.dominant.resize(first + spec.count, false);
        for i in pick(seed, Purpose::Dominance, b, first, spec.count, n_dom) {
            world.dominant[i] = true;
        }
        let n_mirror =
            (scene.rewards.extensions.mirrored_share * spec.count as f32).round() as usize;
        mirrored.resize(first + spec.count, false);
        for i in pick(seed, Purpose::Handedness, b, first, spec.count, n_mirror) {
            mirrored[i] = true;
        }
        first += spec.count;
    }
    let n = first;
    world.position = vec![Vec3::ZERO; n];
    world.heading = vec![Vec3::Z; n];
    world.roll = vec![0.0; n];
    world.speed = vec![0.0; n];
    world.chase = vec![Chase::None; n];

    let of = |i: usize| &info[world.behaviour[i] as usize];
    let half: Vec<Vec3> = (0..n)
        .map(|i| of(i).collider_bl * 0.5 * world.bl[i])
        .collect();
    let bound: Vec<f32> = half.iter().map(|h| h.length()).collect();
    let traits = Traits {
        max_bound: bound.iter().copied().fold(0.025, f32::max),
        bound,
        half,
        visual: (0..n)
            .map(|i| {
                scene.behaviours[world.behaviour[i] as usize]
                    .species
                    .visual_radius_bl
                    * world.bl[i]
            })
            .collect(),
        sense: (0..n).map(|i| of(i).sense_bl * world.bl[i]).collect(),
        params: (0..n).map(|i| of(i).params).collect(),
        mirrored,
        mirroring: true,
    };
    (info, world, traits)
}

/// `k` of the fish `first..first + count` of behaviour `b`, by a partial
/// shuffle of the stream `(seed, purpose, b)`.
fn pick(
    seed: u64,
    purpose: Purpose,
    b: usize,
    first: usize,
    count: usize,
    k: usize,
) -> impl Iterator<Item = usize> {
    let mut idx: Vec<usize> = (first..first + count).collect();
    let mut s = Stream::new(seed, purpose, b as u64, 0);
    for j in 0..k.min(count) {
        let pick = j + s.below(idx.len() - j);
        idx.swap(j, pick);
    }
    idx.truncate(k.min(count));
    idx.into_iter()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_are_checked() {
        let ok = FishParams {
            speed_bl: [0.2, 1.9],
            light_steep: [-20.0, 1000.0],
        };
        assert!(ok.check().is_ok());
        // Foids at night: [0, 0.4] is allowed.
        assert!(
            FishParams {
                speed_bl: [0.0, 0.4],
                ..ok
            }
            .check()
            .is_ok()
        );
        for bad in [
            FishParams {
                speed_bl: [0.5, 0.2],
                ..ok
            },
            FishParams {
                speed_bl: [-0.1, 1.0],
                ..ok
            },
            FishParams {
                speed_bl: [0.0, f32::NAN],
                ..ok
            },
            FishParams {
                light_steep: [7.0, 409.0],
                ..ok
            },
        ] {
            assert!(bad.check().is_err(), "{bad:?}");
        }
    }
}
