//! The sensing stage (SPEC §5): what a fish sees and knows at a decision.
//!
//! For fish `i` with sensing range `d_sense` (its species' range in BL times
//! its body length), one pass over the boundaries, the obstacles and the
//! neighbours within `d_sense` (from the spatial grid, in its fixed order):
//! * fills the newest grid frame: boundaries and obstacles by casting each
//!   cell's centre ray, neighbours as spheres of their visual radius (the
//!   chase partner with its own channel);
//! * sums the surroundings the reward needs ([`Surroundings`]): the boundary
//!   closeness `Σ (d_sense − d_i)/d_sense` (boundaries and obstacles within
//!   range) and the alignment `Σ (90 − Δθ_j)/90` (neighbours within range);
//! * finds the nearest neighbour in front (for `u_t`) and, for a free dominant
//!   fish, the nearest free subordinate of its species (a chase target).
//!
//! The vector observation is `[u_x, u_y, u_z, depth / H, aggressor, target]`
//! in the fish's local frame, `u = (0, 0, 1) − R⁻¹·f_front` (zero without a
//! neighbour in front). With the profile's `heading_of = "closing"` (not in
//! the sources) `u` is of the neighbour that will come closest within
//! [`CLOSING_HORIZON_S`] instead ([`closest_approach`]); with `heading_of =
//! "rewarded"` (not in the sources either) `u` is of the mean heading of the
//! neighbours `r_ND` is paid for.

use crate::config::{Extensions, HeadingOf, NeighbourForm, NeighbourWeight, PersonalSpaceOf};
use crate::kinematics::{basis, fast_acos_deg};
use crate::traits::Traits;
use crate::world::{Chase, World};
use deepfoids_sensors::{
    Boundary, Frame, GridSensor, Obstacle, SeenKind, SpatialGrid, SphereBatch,
};
use glam::Vec3;

/// What the sensor pass found around one fish.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Surroundings {
    /// `Σ (d_sense − d_i)/d_sense` over boundaries and obstacles within range.
    pub boundary_sum: f32,
    /// `Σ (90 − Δθ_j)/90` over neighbours within range (with SPEC §6.2's
    /// extensions: outside the personal space, conspecific, size-weighted, or
    /// the mean instead of the sum, as the profile says).
    pub alignment_sum: f32,
    /// Neighbours inside the personal space (SPEC §6.2; 0 when it is off),
    /// each weighted by `1 + m · (1 − alignment)` with the profile's
    /// `personal_space_misalignment` m (1 when it is off).
    pub crowding: f32,
    /// The neighbour whose heading `u` gives: the nearest in front, or with
    /// `heading_of = "closing"` the one coming closest.
    pub nearest_front: Option<u32>,
    /// `Σ` of the headings of the neighbours `alignment_sum` counts, summed
    /// only with `heading_of = "rewarded"` (zero otherwise: the hot path skips it).
    pub rewarded_heading: Vec3,
    pub nearest_subordinate: Option<u32>,
}

/// What sensing reads of a neighbour, gathered in the sensing grid's entry
/// order ([`SpatialGrid::entries`]) so that the candidates of a query are read
/// from contiguous memory, as their positions are, and not from the world's
/// arrays at scattered indices (in the 30,000-fish cage, under `perf`, those
/// reads had been a third of `Sensing::sense`'s own time).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Neighbour {
    heading: Vec3,
    speed: f32,
    bl: f32,
    species: u16,
    /// Not dominant and in no chase: a dominant fish may chase it.
    free_subordinate: bool,
}

/// Fill `out[slot]` with what sensing reads of the fish at `grid`'s `slot`.
pub(crate) fn gather_neighbours(world: &World, grid: &SpatialGrid, out: &mut [Neighbour]) {
    for (n, &j) in out.iter_mut().zip(grid.entries()) {
        let j = j as usize;
        *n = Neighbour {
            heading: world.heading[j],
            speed: world.speed[j],
            bl: world.bl[j],
            species: world.species[j],
            free_subordinate: !world.dominant[j] && world.chase[j] == Chase::None,
        };
    }
}

/// Read-only view of what sensing needs.
pub(crate) struct Sensing<'a> {
    pub world: &'a World,
    pub traits: &'a Traits,
    pub boundaries: &'a [Boundary],
    pub obstacles: &'a [Obstacle],
    pub sensor: &'a GridSensor,
    /// Neighbours, rebuilt with the visual radii before the pass.
    pub grid: &'a SpatialGrid,
    /// What sensing reads of each neighbour, in `grid`'s entry order
    /// ([`gather_neighbours`] after the grid's rebuild and after chases change).
    pub neighbours: &'a [Neighbour],
    pub cage_height: f32,
    /// `r_ND` over at most this many nearest neighbours (0: all).
    pub neighbour_cap: usize,
    /// How `r_ND` counts neighbours (SPEC §6.2).
    pub extensions: Extensions,
}

/// `Σ_i (d_sense − d_i)/d_sense` over the boundaries and obstacles within
/// `range` of `p` (SPEC §6, `r_BD`'s sum; a point beyond a plane counts as at it).
pub(crate) fn boundary_closeness(
    p: Vec3,
    range: f32,
    boundaries: &[Boundary],
    obstacles: &[Obstacle],
) -> f32 {
    let near = |d: f32| {
        if d < range {
            (range - d.max(0.0)) / range
        } else {
            0.0
        }
    };
    boundaries
        .iter()
        .map(|b| near(b.plane.distance(p)))
        .chain(obstacles.iter().map(|o| near(o.distance(p))))
        .sum()
}

/// The `K` nearest neighbours' alignment terms (and headings) seen so far,
/// by distance.
struct Nearest<const K: usize> {
    d: [f32; K],
    a: [f32; K],
    h: [Vec3; K],
    len: usize,
}

impl<const K: usize> Nearest<K> {
    fn new() -> Self {
        Self {
            d: [f32::INFINITY; K],
            a: [0.0; K],
            h: [Vec3::ZERO; K],
            len: 0,
        }
    }

    /// Keep `(d, a, h)` if it is among the `cap` (≤ K) nearest so far.
    fn offer(&mut self, cap: usize, d: f32, a: f32, h: Vec3) {
        let cap = cap.min(K);
        if self.len == cap && d >= self.d[cap - 1] {
            return;
        }
        let mut k = self.len.min(cap - 1);
        if self.len < cap {
            self.len += 1;
        }
        while k > 0 && self.d[k - 1] > d {
            self.d[k] = self.d[k - 1];
            self.a[k] = self.a[k - 1];
            self.h[k] = self.h[k - 1];
            k -= 1;
        }
        self.d[k] = d;
        self.a[k] = a;
        self.h[k] = h;
    }

    fn sum(&self) -> f32 {
        self.a[..self.len].iter().sum()
    }

    fn heading_sum(&self) -> Vec3 {
        self.h[..self.len].iter().sum()
    }
}

pub use crate::limits::MAX_NEIGHBOUR_CAP;

/// r_ND's term of one neighbour, `(90 − Δθ)/90` (Eq. 4.5's r_ND; `Δθ` in
/// degrees between the unit headings `f` and `h`).
#[inline]
fn alignment(f: Vec3, h: Vec3) -> f32 {
    (90.0 - fast_acos_deg(f.dot(h))) / 90.0
}

/// Whether a neighbour at squared distance `d2`, `along` ahead on the fish's
/// heading, is inside SPEC §6.2's personal space of `radius` (m): the sphere,
/// or with `ahead > 0` the ellipsoid stretched to `ahead` along the lane in
/// front (`Extensions::personal_space_ahead_bl`).
#[inline]
fn personal_space_holds(d2: f32, along: f32, radius: f32, ahead: f32) -> bool {
    let r2 = radius * radius;
    if ahead > 0.0 && along > 0.0 {
        let off2 = (d2 - along * along).max(0.0);
        along * along * r2 + off2 * ahead * ahead < r2 * ahead * ahead
    } else {
        d2 < r2
    }
}

/// How far ahead `heading_of = "closing"` looks (s): about what a coho
/// swims in one body length at its 1–1.5 BL/s, the length of the collider a
/// contact is an overlap of.
pub const CLOSING_HORIZON_S: f32 = 1.0;

/// The least distance between two fish within the next `horizon` seconds if
/// both keep their velocities: `rel` is the neighbour's offset, `v_rel` its
/// velocity relative to the fish's. `|rel + v_rel·t*|` with
/// `t* = clamp(−rel·v_rel / |v_rel|², 0, horizon)`.
pub(crate) fn closest_approach(rel: Vec3, v_rel: Vec3, horizon: f32) -> f32 {
    let vv = v_rel.length_squared();
    let t = if vv > 1e-12 {
        (-rel.dot(v_rel) / vv).clamp(0.0, horizon)
    } else {
        0.0
    };
    (rel + v_rel * t).length()
}

impl Sensing<'_> {
    /// Fill `frame` with what fish `i` sees and sum up its surroundings. A
    /// mirrored fish (the profile's `mirrored_share`) sees the frame mirrored.
    pub fn sense(&self, i: usize, frame: &mut Frame) -> Surroundings {
        let w = self.world;
        let range = self.traits.sense[i];
        frame.clear(range);
        let (p, f) = (w.position[i], w.heading[i]);
        let rot = basis(f, w.roll[i]);
        let to_local = rot.transpose();
        let mut seen = Surroundings {
            boundary_sum: boundary_closeness(p, range, self.boundaries, self.obstacles),
            ..Surroundings::default()
        };
        for bd in self.boundaries {
            let d = bd.plane.distance(p);
            if d < range {
                frame.add_plane(
                    self.sensor,
                    to_local * bd.plane.normal,
                    d.max(0.0),
                    SeenKind::from(bd.kind),
                );
            }
        }
        for o in self.obstacles {
            let d = o.distance(p);
            if d < range {
                frame.add_obstacle(self.sensor, p, rot, o);
            }
        }
        let partner = w.chase[i].partner();
        let wants_target = w.dominant[i] && w.chase[i] == Chase::None;
        let (mut front_d, mut sub_d) = (f32::INFINITY, f32::INFINITY);
        let closing = self.extensions.heading_of == HeadingOf::Closing;
        let rewarded = self.extensions.heading_of == HeadingOf::Rewarded;
        let (v_i, mut closest) = (f * w.speed[i], (f32::INFINITY, f32::INFINITY));
        let range2 = range * range;
        let mut spheres = SphereBatch::new();
        let cap = self.neighbour_cap;
        let ext = &self.extensions;
        let personal_bl = ext.personal_space_bl;
        let ahead_bl = ext.personal_space_ahead_bl;
        let misalignment = ext.personal_space_misalignment;
        let mut eligible = 0u32;
        let mut nearest = Nearest::<MAX_NEIGHBOUR_CAP>::new();
        let (species, bl) = (w.species[i], w.bl[i]);
        self.grid.for_each_candidate_slot(p, range, |slot, j, q| {
            let rel = q.truncate() - p;
            let d2 = rel.length_squared();
            if d2 >= range2 || j == i {
                return;
            }
            let n = &self.neighbours[slot];
            let d = d2.sqrt();
            let len = match ext.personal_space_of {
                PersonalSpaceOf::Own => bl,
                PersonalSpaceOf::Pair => 0.5 * (bl + n.bl),
            };
            let along = rel.dot(f);
            let inside = personal_space_holds(d2, along, personal_bl * len, ahead_bl * len);
            if inside {
                seen.crowding += if misalignment > 0.0 {
                    1.0 + misalignment * (1.0 - alignment(f, n.heading))
                } else {
                    1.0
                };
            } else if !ext.conspecific_only || n.species == species {
                eligible += 1;
                let mut align = alignment(f, n.heading);
                if ext.size_weighted {
                    align *= bl.min(n.bl) / bl.max(n.bl);
                }
                if ext.neighbour_weight == NeighbourWeight::Proximity {
                    align *= 4.0 * (1.0 - d / range);
                }
                if cap == 0 {
                    seen.alignment_sum += align;
                    if rewarded {
                        seen.rewarded_heading += n.heading;
                    }
                } else {
                    nearest.offer(cap, d, align, n.heading);
                }
            }
            if closing {
                let v_rel = n.heading * n.speed - v_i;
                let key = (closest_approach(rel, v_rel, CLOSING_HORIZON_S), d);
                if key < closest {
                    closest = key;
                    seen.nearest_front = Some(j as u32);
                }
            } else if along > 0.0 && d < front_d {
                front_d = d;
                seen.nearest_front = Some(j as u32);
            }
            if wants_target && n.species == species && n.free_subordinate && d < sub_d {
                sub_d = d;
                seen.nearest_subordinate = Some(j as u32);
            }
            let kind = if partner == Some(j) {
                SeenKind::ChasePartner
            } else {
                SeenKind::Fish
            };
            if spheres.push(to_local * rel, q.w, kind) {
                frame.add_spheres(self.sensor, &spheres);
                spheres.clear();
            }
        });
        frame.add_spheres(self.sensor, &spheres);
        // The neighbours r_ND is paid for: every eligible one, or the `cap` nearest.
        let counted = if cap > 0 {
            seen.alignment_sum = nearest.sum();
            if rewarded {
                seen.rewarded_heading = nearest.heading_sum();
            }
            nearest.len as u32
        } else {
            eligible
        };
        if eligible < ext.neighbour_quorum {
            seen.alignment_sum = 0.0;
        } else if counted > 0 {
            match ext.neighbour_form {
                NeighbourForm::Sum => {
                    let budget = ext.neighbour_budget;
                    if budget > 0 && counted > budget {
                        seen.alignment_sum *= budget as f32 / counted as f32;
                    }
                }
                NeighbourForm::Mean => seen.alignment_sum /= counted as f32,
                NeighbourForm::Sqrt => seen.alignment_sum /= (counted as f32).sqrt(),
            }
        }
        if self.traits.is_mirrored(i) {
            frame.mirror();
        }
        seen
    }

    /// `[u (3), depth / H, aggressor, target]`; the roles are those of the state
    /// now. A mirrored fish sees `u_x` negated. `u` is of the nearest fish in
    /// front, the closing one, or the rewarded neighbours' mean heading, as
    /// the profile's `heading_of` says.
    pub fn vector_obs(&self, i: usize, seen: &Surroundings, out: &mut [f32]) {
        let w = self.world;
        let heading = if self.extensions.heading_of == HeadingOf::Rewarded {
            seen.rewarded_heading.try_normalize()
        } else {
            seen.nearest_front.map(|j| w.heading[j as usize])
        };
        let u = match heading {
            Some(h) => Vec3::Z - basis(w.heading[i], w.roll[i]).transpose() * h,
            None => Vec3::ZERO,
        };
        out[0] = if self.traits.is_mirrored(i) {
            -u.x
        } else {
            u.x
        };
        out[1] = u.y;
        out[2] = u.z;
        out[3] = -w.position[i].y / self.cage_height;
        out[4] = matches!(w.chase[i], Chase::Aggressor { .. }) as u8 as f32;
        out[5] = matches!(w.chase[i], Chase::Target { .. }) as u8 as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A neighbour 1 m to the side closing at (−1, 0, 1): t* = 1/2 s, then
    /// (0.5, 0, 0.5) apart, 0.7071 m; a horizon of 1/4 s stops it at
    /// (0.75, 0, 0.25), 0.7906 m; one moving away or keeping pace is at its
    /// closest now.
    #[test]
    fn closest_approach_by_hand() {
        let rel = Vec3::X;
        let near = |v: Vec3, h: f32| closest_approach(rel, v, h);
        assert!((near(Vec3::new(-1.0, 0.0, 1.0), 1.0) - 0.5f32.sqrt()).abs() < 1e-6);
        assert!((near(Vec3::new(-1.0, 0.0, 1.0), 0.25) - 0.625f32.sqrt()).abs() < 1e-6);
        assert_eq!(near(Vec3::X, 1.0), 1.0);
        assert_eq!(near(Vec3::ZERO, 1.0), 1.0);
    }
}
