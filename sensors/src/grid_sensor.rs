//! The angular grid vision sensor (SPEC §5).
//!
//! A 34 × 20 grid over the fish's visual field, in its local frame (origin at
//! the body centre, +z forward, +y up, +x to the fish's left — right-handed):
//!
//! * 34 azimuth columns of 10°, centred on the heading, from −170° (left,
//!   column 0) to +170° (right, column 33); the 20° sector straight behind is blind.
//!   Azimuth is measured positive to the fish's right: `az = atan2(−x, z)`.
//! * 20 elevation rows of 9°, from +90° (up, row 0) to −90° (down, row 19):
//!   `el = asin(y)`.
//!
//! Each cell holds 6 channels `[proximity, fish, net, surface, obstacle,
//! chase partner]`: proximity is `1 − dist/d_sense` of the closest object seen
//! in the cell within `d_sense` (0 if none), the other five the one-hot type of
//! that object. A frame is laid out channel-major, `[C, H, W] = [6, 20, 34]`;
//! three frames are stacked oldest first into `[18, 20, 34]`.
//!
//! How things are seen:
//! * a neighbour is a sphere of its visual radius around its centre: it covers
//!   every cell whose centre direction lies within its angular radius
//!   `asin(r / dist)`, and always the cell its centre lies in (so a small, far
//!   fish still shows); its distance is the centre distance;
//! * boundaries and obstacles are found by casting each cell's centre ray.

use crate::frames::{FRAME_BYTES, FrameCell, proximity_byte};
use crate::geometry::{BoundaryKind, Obstacle};
pub use crate::layout::{
    AZ_CELLS, CELLS, CHANNELS, EL_CELLS, FRAME_LEN, STACK, STACKED_CHANNELS, STACKED_LEN,
};
use glam::{Mat3, Vec3};
use std::f32::consts::{FRAC_PI_2, PI};

/// Azimuth cell width (degrees).
pub const AZ_STEP_DEG: f32 = 10.0;
/// Elevation cell height (degrees).
pub const EL_STEP_DEG: f32 = 9.0;
/// Half-width of the seen azimuth range (degrees); beyond it is the blind sector.
pub const AZ_LIMIT_DEG: f32 = AZ_STEP_DEG * AZ_CELLS as f32 / 2.0;

/// The channels of a frame, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Channel {
    Proximity = 0,
    Fish = 1,
    Net = 2,
    Surface = 3,
    Obstacle = 4,
    ChasePartner = 5,
}

/// What the closest object seen in a cell is (its one-hot channel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum SeenKind {
    Fish = 1,
    Net = 2,
    Surface = 3,
    Obstacle = 4,
    ChasePartner = 5,
}

impl From<BoundaryKind> for SeenKind {
    fn from(k: BoundaryKind) -> Self {
        match k {
            BoundaryKind::Net => SeenKind::Net,
            BoundaryKind::Surface => SeenKind::Surface,
        }
    }
}

/// The fixed geometry of the sensor: the centre direction of every cell.
#[derive(Clone, Debug)]
pub struct GridSensor {
    // Cell centre directions in the local frame, structure of arrays for SIMD.
    dx: [f32; CELLS],
    dy: [f32; CELLS],
    dz: [f32; CELLS],
    /// Sine of the lower edge of each row (row 0 spans 81°–90°).
    row_floor_sin: [f32; EL_CELLS],
    /// Sine of each row's centre elevation (the cells' rays).
    row_centre_sin: [f32; EL_CELLS],
}

impl Default for GridSensor {
    fn default() -> Self {
        Self::new()
    }
}

impl GridSensor {
    pub fn new() -> Self {
        let mut s = Self {
            dx: [0.0; CELLS],
            dy: [0.0; CELLS],
            dz: [0.0; CELLS],
            row_floor_sin: std::array::from_fn(|h| {
                (90.0 - EL_STEP_DEG * (h as f32 + 1.0)).to_radians().sin()
            }),
            row_centre_sin: std::array::from_fn(|h| Self::elevation_deg(h).to_radians().sin()),
        };
        for h in 0..EL_CELLS {
            for w in 0..AZ_CELLS {
                let d = direction(
                    Self::azimuth_deg(w).to_radians(),
                    Self::elevation_deg(h).to_radians(),
                );
                let c = h * AZ_CELLS + w;
                (s.dx[c], s.dy[c], s.dz[c]) = (d.x, d.y, d.z);
            }
        }
        s
    }

    /// Centre azimuth of column `w` (degrees, positive to the right).
    pub fn azimuth_deg(w: usize) -> f32 {
        -AZ_LIMIT_DEG + AZ_STEP_DEG * (w as f32 + 0.5)
    }

    /// Centre elevation of row `h` (degrees, positive up).
    pub fn elevation_deg(h: usize) -> f32 {
        90.0 - EL_STEP_DEG * (h as f32 + 0.5)
    }

    /// Centre direction of cell `(h, w)` in the local frame.
    pub fn cell_direction(&self, h: usize, w: usize) -> Vec3 {
        let c = h * AZ_CELLS + w;
        Vec3::new(self.dx[c], self.dy[c], self.dz[c])
    }

    /// The cell `(h, w)` a local unit direction falls in; `None` in the blind sector.
    pub fn cell_of(&self, dir: Vec3) -> Option<(usize, usize)> {
        let az = fast_atan2(-dir.x, dir.z);
        let limit = AZ_LIMIT_DEG.to_radians();
        if az.abs() >= limit {
            return None;
        }
        let w = (((az + limit) / AZ_STEP_DEG.to_radians()) as usize).min(AZ_CELLS - 1);
        let h: usize = self
            .row_floor_sin
            .iter()
            .map(|&e| (dir.y < e) as usize)
            .sum();
        Some((h.min(EL_CELLS - 1), w))
    }
}

/// Reverse the azimuth columns of grids laid out as rows of [`AZ_CELLS`]
/// cells (a frame's channels, a stack of frames, as floats or as bytes): the
/// left–right mirror image of every row.
pub fn mirror_columns<T>(cells: &mut [T]) {
    debug_assert_eq!(cells.len() % AZ_CELLS, 0);
    for row in cells.chunks_exact_mut(AZ_CELLS) {
        row.reverse();
    }
}

/// Local unit direction for azimuth `az` (positive right) and elevation `el` (radians).
#[inline]
pub fn direction(az: f32, el: f32) -> Vec3 {
    let (sa, ca) = az.sin_cos();
    let (se, ce) = el.sin_cos();
    Vec3::new(-sa * ce, se, ca * ce)
}

/// Azimuth (positive right) and elevation of a local unit direction (radians).
#[inline]
pub fn angles(dir: Vec3) -> (f32, f32) {
    (fast_atan2(-dir.x, dir.z), dir.y.clamp(-1.0, 1.0).asin())
}

/// `atan2(y, x)` by a degree-11 minimax polynomial for atan on [0, 1]
/// (error < 1e−5 rad, 0.0006°; the sensor's cells are 10° wide). Used by every
/// azimuth the sensor computes, so cell assignment is consistent.
#[inline]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    // Branch-free (selects only), so loops over many directions vectorise.
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    let a = lo / hi.max(f32::MIN_POSITIVE);
    let a2 = a * a;
    let r = a
        * (0.999_977_26
            + a2 * (-0.332_623_47
                + a2 * (0.193_543_46
                    + a2 * (-0.116_432_87 + a2 * (0.052_653_32 + a2 * -0.011_721_2)))));
    let r = if ay > ax { FRAC_PI_2 - r } else { r };
    let r = if x < 0.0 { PI - r } else { r };
    if y < 0.0 { -r } else { r }
}

/// The bits `lo..=hi` of a row's column mask (none when `lo > hi`).
fn columns_mask((lo, hi): (usize, usize)) -> u64 {
    if lo > hi {
        0
    } else {
        (u64::MAX >> (63 - hi)) & (u64::MAX << lo)
    }
}

/// How far past a sphere's angular bounds (radians, and the same in sines)
/// [`Frame::add_spheres`] still looks for cell centres: the exact test is a
/// float dot product against `cos α`, which near α = 0 can pass a centre up to
/// ≈ 3.5e−4 rad outside the disc, so the bounds keep every cell it can pass.
const BOUNDS_SLACK: f32 = 2e-3;

/// `x.floor()` for |x| < 2³¹ without `floorf` (x86-64's baseline has no
/// rounding instruction, so `floor()` is a library call): the truncation,
/// less one where it lies above `x`.
#[inline]
fn floor(x: f32) -> f32 {
    let t = x as i32 as f32;
    t - (t > x) as i32 as f32
}

/// `x.ceil()` for |x| < 2³¹ without `ceilf` (see [`floor`]); −0 comes out as 0.
#[inline]
fn ceil(x: f32) -> f32 {
    let t = x as i32 as f32;
    t + (t < x) as i32 as f32
}

/// Spheres set up together by [`Frame::add_spheres`].
pub const SPHERE_BATCH: usize = 256;

/// Up to [`SPHERE_BATCH`] spheres (relative centre in the local frame, radius,
/// kind), structure of arrays. Lives on the stack.
#[derive(Clone, Debug)]
pub struct SphereBatch {
    x: [f32; SPHERE_BATCH],
    y: [f32; SPHERE_BATCH],
    z: [f32; SPHERE_BATCH],
    r: [f32; SPHERE_BATCH],
    kind: [u8; SPHERE_BATCH],
    len: usize,
}

impl Default for SphereBatch {
    fn default() -> Self {
        Self::new()
    }
}

impl SphereBatch {
    pub fn new() -> Self {
        Self {
            x: [0.0; SPHERE_BATCH],
            y: [0.0; SPHERE_BATCH],
            z: [0.0; SPHERE_BATCH],
            r: [0.0; SPHERE_BATCH],
            kind: [0; SPHERE_BATCH],
            len: 0,
        }
    }

    /// Add a sphere; returns `true` when the batch is now full.
    #[inline]
    pub fn push(&mut self, rel: Vec3, radius: f32, kind: SeenKind) -> bool {
        let i = self.len;
        (self.x[i], self.y[i], self.z[i], self.r[i], self.kind[i]) =
            (rel.x, rel.y, rel.z, radius, kind as u8);
        self.len += 1;
        self.len == SPHERE_BATCH
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn clear(&mut self) {
        self.len = 0;
    }
}

/// One frame under construction: per cell the distance and kind of the closest
/// object seen so far. Lives on the stack; `clear` before each use.
#[derive(Clone, Debug)]
pub struct Frame {
    range: f32,
    dist: [f32; CELLS],
    kind: [u8; CELLS],
}

impl Frame {
    /// An empty frame for sensing range `range` (m).
    pub fn new(range: f32) -> Self {
        Self {
            range,
            dist: [range; CELLS],
            kind: [0; CELLS],
        }
    }

    /// Forget everything and set the sensing range (m).
    pub fn clear(&mut self, range: f32) {
        self.range = range;
        self.dist.fill(range);
        self.kind.fill(0);
    }

    /// The left–right mirror image: the azimuth columns reversed (column `w`
    /// and `AZ_CELLS − 1 − w` are centred at opposite azimuths), the rows as
    /// they are. What a fish seeing the mirrored world would see; twice is
    /// the identity.
    pub fn mirror(&mut self) {
        mirror_columns(&mut self.dist);
        mirror_columns(&mut self.kind);
    }

    /// Sensing range (m).
    pub fn range(&self) -> f32 {
        self.range
    }

    /// A sphere of radius `radius` whose centre is at `rel` in the local frame,
    /// seen at its centre distance. (A batch of one: see [`Frame::add_spheres`].)
    pub fn add_sphere(&mut self, sensor: &GridSensor, rel: Vec3, radius: f32, kind: SeenKind) {
        let mut batch = SphereBatch::new();
        batch.push(rel, radius, kind);
        self.add_spheres(sensor, &batch);
    }

    /// Spheres (neighbours) in the local frame; each covers the cells whose
    /// centre direction lies within its angular radius `asin(r/d)` and the
    /// cell its centre falls in, at its centre distance `d`. A cell keeps the
    /// nearest object (the first of equals), so the order of the spheres does
    /// not change the frame.
    ///
    /// Candidate cells come from bounds that need no trigonometry but one
    /// polynomial `atan2`: with `y = sin el`, `s = sin α = r/d`, `c = cos α`,
    /// `sin(el ± α) = y·c ± cos el·s` picks the rows and `asin(x) ≤ x / √(1 − x²)`,
    /// `x = s / cos el_max`, bounds the azimuth half-width. A cell is tested at
    /// its centre, so only rows and columns whose *centre* lies within those
    /// bounds (plus [`BOUNDS_SLACK`]) are candidates: in a dense school most
    /// spheres are far and span less than a cell, and bounds by the cells'
    /// edges made three of every four tests fail. Every candidate is then
    /// tested exactly (the frame is the same as testing every cell).
    /// The set-up runs as loops over the whole batch, which vectorise.
    ///
    /// The spheres are then drawn nearest first, and a bit per cell marks the
    /// cells a sphere of this batch has taken: such a cell holds a distance no
    /// greater than any later sphere's, so it is skipped without a test. In a
    /// dense school the nearest few neighbours cover most of what the far ones
    /// would, and the far ones cost little more than their set-up.
    pub fn add_spheres(&mut self, sensor: &GridSensor, batch: &SphereBatch) {
        let n = batch.len;
        let range2 = self.range * self.range;
        let (mut d, mut ux, mut uy, mut uz) = (
            [0f32; SPHERE_BATCH],
            [0f32; SPHERE_BATCH],
            [0f32; SPHERE_BATCH],
            [0f32; SPHERE_BATCH],
        );
        let (mut az, mut cos_a, mut half) = (
            [0f32; SPHERE_BATCH],
            [0f32; SPHERE_BATCH],
            [0f32; SPHERE_BATCH],
        );
        // The bounds' sines, widened by the slack.
        let (mut sin_hi, mut sin_lo) = ([0f32; SPHERE_BATCH], [0f32; SPHERE_BATCH]);
        // Nearest first: the distance's bits (positive floats order as their
        // bits) above the index, so equal distances keep the batch's order.
        let mut order = [0u64; SPHERE_BATCH];
        let mut valid = 0;
        for i in 0..n {
            let d2 = batch.x[i] * batch.x[i] + batch.y[i] * batch.y[i] + batch.z[i] * batch.z[i];
            let di = d2.max(1e-12).sqrt();
            let inv = 1.0 / di;
            d[i] = di;
            (ux[i], uy[i], uz[i]) = (batch.x[i] * inv, batch.y[i] * inv, batch.z[i] * inv);
            if d2 < range2 && d2 > 1e-12 {
                order[valid] = (u64::from(di.to_bits()) << 32) | i as u64;
                valid += 1;
            }
        }
        for i in 0..n {
            az[i] = fast_atan2(-ux[i], uz[i]);
        }
        for i in 0..n {
            let y = uy[i].clamp(-1.0, 1.0);
            let cos_el = (1.0 - y * y).max(0.0).sqrt();
            let s = (batch.r[i] / d[i]).min(1.0);
            let c = (1.0 - s * s).max(0.0).sqrt();
            cos_a[i] = c;
            // Rows: el ± α; past a pole (cosine < 0) the band reaches it.
            let (cos_hi, cos_lo) = (cos_el * c - y * s, cos_el * c + y * s);
            sin_hi[i] = if cos_hi < 0.0 {
                2.0
            } else {
                y * c + cos_el * s + BOUNDS_SLACK
            };
            sin_lo[i] = if cos_lo < 0.0 {
                -2.0
            } else {
                y * c - cos_el * s - BOUNDS_SLACK
            };
            // Columns: cos el_max = cos(|el| + α).
            let cos_el_max = cos_el * c - y.abs() * s;
            let t = if cos_el_max > 1e-6 {
                s / cos_el_max
            } else {
                1.0
            };
            half[i] = if t < 0.999 {
                t / (1.0 - t * t).max(1e-12).sqrt()
            } else {
                2.0 * PI
            };
        }
        // The row the centre falls in, and the rows `first..end` whose centre
        // elevation lies within the bounds (rows run from the top down).
        let (mut row_c, mut first, mut end) = (
            [0u8; SPHERE_BATCH],
            [0u8; SPHERE_BATCH],
            [0u8; SPHERE_BATCH],
        );
        for (&edge, &centre) in sensor.row_floor_sin.iter().zip(&sensor.row_centre_sin) {
            for i in 0..n {
                row_c[i] += (uy[i] < edge) as u8;
                first[i] += (centre > sin_hi[i]) as u8;
                end[i] += (centre >= sin_lo[i]) as u8;
            }
        }
        let order = &mut order[..valid];
        order.sort_unstable();
        let limit = AZ_LIMIT_DEG.to_radians();
        let step_az = AZ_STEP_DEG.to_radians();
        let col = |a: f32| ((a + limit) / step_az).clamp(0.0, (AZ_CELLS - 1) as f32) as usize;
        // The columns whose centre azimuth lies in `lo..=hi` (plus the slack).
        let centres = |lo: f32, hi: f32| {
            let a = ceil((lo - BOUNDS_SLACK + limit) / step_az - 0.5).max(0.0);
            let b = floor((hi + BOUNDS_SLACK + limit) / step_az - 0.5);
            if b < a || a > (AZ_CELLS - 1) as f32 {
                (1, 0)
            } else {
                (a as usize, b.min((AZ_CELLS - 1) as f32) as usize)
            }
        };
        let none = (1, 0);
        // Bit `w` of `taken[h]`: cell (h, w) holds a sphere of this batch.
        let mut taken = [0u64; EL_CELLS];
        for &key in order.iter() {
            let i = (key & 0xffff_ffff) as usize;
            let (di, k) = (d[i], batch.kind[i]);
            // The cell the centre falls in.
            if az[i].abs() < limit {
                let (h, w) = ((row_c[i] as usize).min(EL_CELLS - 1), col(az[i]));
                let c = h * AZ_CELLS + w;
                if di < self.dist[c] {
                    self.dist[c] = di;
                    self.kind[c] = k;
                    taken[h] |= 1 << w;
                }
            }
            let rows = first[i] as usize..end[i] as usize;
            // Column ranges; a range wrapping past ±180° (behind the fish) splits in two.
            let (main, wrapped) = if half[i] >= PI {
                ((0, AZ_CELLS - 1), none) // around a pole: every column
            } else {
                let (az_lo, az_hi) = (az[i] - half[i], az[i] + half[i]);
                let wrapped = if az_hi > PI {
                    centres(-PI, az_hi - 2.0 * PI)
                } else if az_lo < -PI {
                    centres(az_lo + 2.0 * PI, PI)
                } else {
                    none
                };
                (centres(az_lo, az_hi), wrapped)
            };
            let columns = columns_mask(main) | columns_mask(wrapped);
            let (dx, dy, dz, c) = (ux[i], uy[i], uz[i], cos_a[i]);
            for (h, taken) in taken.iter_mut().enumerate().take(rows.end).skip(rows.start) {
                let mut todo = columns & !*taken;
                while todo != 0 {
                    let w = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let cell = h * AZ_CELLS + w;
                    let cos = sensor.dx[cell] * dx + sensor.dy[cell] * dy + sensor.dz[cell] * dz;
                    if cos >= c && di < self.dist[cell] {
                        self.dist[cell] = di;
                        self.kind[cell] = k;
                        *taken |= 1 << w;
                    }
                }
            }
        }
    }

    /// A plane at distance `dist` (m, ≥ 0) whose unit normal — pointing from the
    /// plane towards the fish — is `normal` in the local frame. Each cell's
    /// centre ray hits it at `t = dist / (−c·n)` when `c·n < 0`.
    pub fn add_plane(&mut self, sensor: &GridSensor, normal: Vec3, dist: f32, kind: SeenKind) {
        if dist >= self.range {
            return;
        }
        let k = kind as u8;
        for c in 0..CELLS {
            let dn = sensor.dx[c] * normal.x + sensor.dy[c] * normal.y + sensor.dz[c] * normal.z;
            let t = dist / -dn;
            if dn < 0.0 && t < self.dist[c] {
                self.dist[c] = t;
                self.kind[c] = k;
            }
        }
    }

    /// An obstacle, cast in the world frame from `origin` with the fish's
    /// local-to-world rotation `rot`.
    pub fn add_obstacle(
        &mut self,
        sensor: &GridSensor,
        origin: Vec3,
        rot: Mat3,
        obstacle: &Obstacle,
    ) {
        if obstacle.distance(origin) >= self.range {
            return;
        }
        for c in 0..CELLS {
            let dir = rot * Vec3::new(sensor.dx[c], sensor.dy[c], sensor.dz[c]);
            if let Some(t) = obstacle.ray_cast(origin, dir, self.dist[c]) {
                self.dist[c] = t;
                self.kind[c] = SeenKind::Obstacle as u8;
            }
        }
    }

    /// The kind seen in cell `(h, w)`, if any.
    pub fn kind_at(&self, h: usize, w: usize) -> Option<SeenKind> {
        match self.kind[h * AZ_CELLS + w] {
            1 => Some(SeenKind::Fish),
            2 => Some(SeenKind::Net),
            3 => Some(SeenKind::Surface),
            4 => Some(SeenKind::Obstacle),
            5 => Some(SeenKind::ChasePartner),
            _ => None,
        }
    }

    /// Write the frame as `[6, 20, 34]` floats into `out` (length [`FRAME_LEN`]).
    pub fn write(&self, out: &mut [f32]) {
        let out = &mut out[..FRAME_LEN];
        let inv = 1.0 / self.range;
        let (prox, types) = out.split_at_mut(CELLS);
        for ((p, &k), &d) in prox.iter_mut().zip(&self.kind).zip(&self.dist) {
            *p = if k != 0 { 1.0 - d * inv } else { 0.0 };
        }
        // One pass per type channel: branch-free and vectorisable.
        for (k, channel) in types.chunks_exact_mut(CELLS).enumerate() {
            let k = k as u8 + 1;
            for (v, &kind) in channel.iter_mut().zip(&self.kind) {
                *v = (kind == k) as u8 as f32;
            }
        }
    }

    /// Write the frame as [`FRAME_BYTES`] bytes into `out`: the proximities as
    /// bytes, then the kinds; the same bytes as [`quantise`] of [`Frame::write`].
    pub fn write_bytes(&self, out: &mut [u8]) {
        let (prox, kinds) = out[..FRAME_BYTES].split_at_mut(CELLS);
        let inv = 1.0 / self.range;
        for ((p, &k), &d) in prox.iter_mut().zip(&self.kind).zip(&self.dist) {
            *p = if k != 0 {
                proximity_byte(1.0 - d * inv)
            } else {
                0
            };
        }
        kinds.copy_from_slice(&self.kind);
    }
}

/// Shift a stacked observation (`[18, 20, 34]` floats, or 3 frames of bytes)
/// one frame older and return the slot of the newest frame for the caller to write.
pub fn push_frame<T: FrameCell>(stack: &mut [T]) -> &mut [T] {
    stack.copy_within(T::FRAME..STACK * T::FRAME, 0);
    &mut stack[(STACK - 1) * T::FRAME..STACK * T::FRAME]
}

/// Clear the history of a stacked observation (a new episode): the older
/// frames become zeros; returns the newest frame's slot.
pub fn reset_stack<T: FrameCell>(stack: &mut [T]) -> &mut [T] {
    stack[..(STACK - 1) * T::FRAME].fill(T::default());
    &mut stack[(STACK - 1) * T::FRAME..STACK * T::FRAME]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `floor` and `ceil` agree with the library's on integers, halves and
    /// their neighbouring floats, both signs, and a sweep (−0 aside, which
    /// `ceil` gives as 0 and `max(0.0)` makes 0 either way).
    #[test]
    fn floor_and_ceil_match_the_library() {
        let mut xs = vec![0.0f32, -0.0, 1e-30, -1e-30, 2.0e9, -2.0e9];
        for k in -80..=80 {
            let x = k as f32 * 0.5;
            xs.extend([
                x,
                f32::from_bits(x.to_bits() + 1),
                f32::from_bits(x.to_bits().max(1) - 1),
            ]);
        }
        xs.extend((-100_000..=100_000).map(|i| i as f32 * 1.37e-3));
        for x in xs {
            assert_eq!(floor(x), x.floor(), "floor({x:e})");
            assert!(ceil(x) == x.ceil(), "ceil({x:e})");
        }
    }

    fn at(frame: &[f32], ch: Channel, h: usize, w: usize) -> f32 {
        frame[ch as usize * CELLS + h * AZ_CELLS + w]
    }

    fn covered(frame: &Frame) -> Vec<(usize, usize)> {
        let mut v = vec![];
        for h in 0..EL_CELLS {
            for w in 0..AZ_CELLS {
                if frame.kind_at(h, w).is_some() {
                    v.push((h, w));
                }
            }
        }
        v
    }

    /// A sphere 23° right and 13° up before a slanted wall, mirrored, is the
    /// frame of the same scene mirrored (x → −x in the local frame: right is
    /// −x): the sphere 23° left, the wall slanted the other way. Twice is the
    /// identity.
    #[test]
    fn a_mirrored_frame_is_the_frame_of_the_mirrored_scene() {
        let sensor = GridSensor::new();
        let frame_of = |side: f32| {
            let mut f = Frame::new(1.0);
            let rel = direction(side * 23f32.to_radians(), 13f32.to_radians()) * 0.6;
            f.add_sphere(&sensor, rel, 0.12, SeenKind::Fish);
            let wall = Vec3::new(side * 0.4, 0.2, -1.0).normalize();
            f.add_plane(&sensor, wall, 0.7, SeenKind::Net);
            f
        };
        let floats = |f: &Frame| {
            let mut out = vec![0.0; FRAME_LEN];
            f.write(&mut out);
            out
        };
        let (right, left) = (frame_of(1.0), frame_of(-1.0));
        assert_ne!(floats(&right), floats(&left));
        let mut mirrored = right.clone();
        mirrored.mirror();
        assert_eq!(floats(&mirrored), floats(&left));
        mirrored.mirror();
        assert_eq!(floats(&mirrored), floats(&right));
    }

    #[test]
    fn cell_centres_span_the_field_of_view() {
        assert_eq!(GridSensor::azimuth_deg(0), -165.0);
        assert_eq!(GridSensor::azimuth_deg(16), -5.0);
        assert_eq!(GridSensor::azimuth_deg(17), 5.0);
        assert_eq!(GridSensor::azimuth_deg(33), 165.0);
        assert_eq!(GridSensor::elevation_deg(0), 85.5);
        assert_eq!(GridSensor::elevation_deg(9), 4.5);
        assert_eq!(GridSensor::elevation_deg(19), -85.5);
        // +x is the fish's left: azimuth −90°.
        let (az, el) = angles(Vec3::X);
        assert!((az.to_degrees() + 90.0).abs() < 1e-4 && el.abs() < 1e-6);
        let sensor = GridSensor::new();
        // Centre of column 8 (−85°) and row 10 (−4.5°).
        let left = direction((-85f32).to_radians(), (-4.5f32).to_radians());
        assert_eq!(sensor.cell_of(left), Some((10, 8)));
        assert_eq!(sensor.cell_of(-Vec3::Z), None);
        assert_eq!(sensor.cell_of(Vec3::Y).map(|c| c.0), Some(0));
    }

    /// A fish straight ahead at 1 m with d_sense 3 m: proximity 1 − 1/3 in the
    /// four centre cells (columns 16–17 at ±5°, rows 9–10 at ±4.5°), type fish.
    /// Angular radius asin(0.15/1) = 8.6° covers those four centres (6.7° off
    /// axis) and none of the next ring (≥ 14.4°).
    #[test]
    fn fish_ahead_fills_the_centre_cells() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        f.add_sphere(&sensor, Vec3::new(0.0, 0.0, 1.0), 0.15, SeenKind::Fish);
        assert_eq!(covered(&f), vec![(9, 16), (9, 17), (10, 16), (10, 17)]);
        let mut out = vec![0.0; FRAME_LEN];
        f.write(&mut out);
        for (h, w) in [(9, 16), (9, 17), (10, 16), (10, 17)] {
            assert!((at(&out, Channel::Proximity, h, w) - (1.0 - 1.0 / 3.0)).abs() < 1e-6);
            assert_eq!(at(&out, Channel::Fish, h, w), 1.0);
            assert_eq!(at(&out, Channel::Net, h, w), 0.0);
        }
        assert_eq!(out.iter().filter(|&&x| x != 0.0).count(), 8);
    }

    /// The same fish at 0.5 m has angular radius 17.5° and covers more cells.
    #[test]
    fn a_nearer_fish_covers_more_cells() {
        let sensor = GridSensor::new();
        let mut far = Frame::new(3.0);
        far.add_sphere(&sensor, Vec3::new(0.0, 0.0, 1.0), 0.15, SeenKind::Fish);
        let mut near = Frame::new(3.0);
        near.add_sphere(&sensor, Vec3::new(0.0, 0.0, 0.5), 0.15, SeenKind::Fish);
        let (n_far, n_near) = (covered(&far).len(), covered(&near).len());
        assert!(n_near > n_far, "{n_near} vs {n_far}");
        // Within 17.5°: (±5, ±4.5) 6.7°, (±15, ±4.5) 15.6°, (±5, ±13.5) 14.4° → 4 + 4 + 4 = 12 cells.
        assert_eq!(n_near, 12);
    }

    /// A tiny far fish still lands in the one cell its centre falls in.
    #[test]
    fn a_tiny_fish_marks_its_centre_cell() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        let dir = direction(32.0f32.to_radians(), -20.0f32.to_radians());
        f.add_sphere(&sensor, dir * 2.5, 0.01, SeenKind::Fish);
        // az 32° → column (32 + 170) / 10 = 20; el −20° → row (90 + 20) / 9 = 12.
        assert_eq!(covered(&f), vec![(12, 20)]);
    }

    /// Nothing is seen in the blind sector straight behind.
    #[test]
    fn the_blind_sector_stays_empty() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        f.add_sphere(&sensor, Vec3::new(0.0, 0.0, -2.0), 0.05, SeenKind::Fish);
        assert!(covered(&f).is_empty());
    }

    /// A plane 1 m to the left (+x) with normal pointing right (−x): cells on the
    /// left half see it at 1/cos(angle to the normal); the right half sees nothing.
    #[test]
    fn a_wall_to_the_left_shows_on_the_left() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        f.add_plane(&sensor, -Vec3::X, 1.0, SeenKind::Net);
        let mut out = vec![0.0; FRAME_LEN];
        f.write(&mut out);
        // Straight left, horizon: column 7 or 8 (az −95°/−85°), row 9 (el 4.5°).
        let c = sensor.cell_direction(9, 8);
        let expected = 1.0 - (1.0 / c.x) / 3.0;
        assert!((at(&out, Channel::Proximity, 9, 8) - expected).abs() < 1e-5);
        assert_eq!(at(&out, Channel::Net, 9, 8), 1.0);
        for h in 0..EL_CELLS {
            for w in 17..AZ_CELLS {
                assert_eq!(
                    at(&out, Channel::Net, h, w),
                    0.0,
                    "right side cell ({h},{w})"
                );
            }
        }
    }

    /// The surface 0.5 m above: seen in the top rows as surface, never below the horizon.
    #[test]
    fn the_surface_above_shows_as_surface() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(1.5);
        f.add_plane(&sensor, -Vec3::Y, 0.5, SeenKind::Surface);
        let mut out = vec![0.0; FRAME_LEN];
        f.write(&mut out);
        // Row 0 (el 85.5°) at the heading column: t = 0.5 / sin 85.5°.
        let t = 0.5 / 85.5f32.to_radians().sin();
        assert!((at(&out, Channel::Proximity, 0, 16) - (1.0 - t / 1.5)).abs() < 1e-5);
        assert_eq!(at(&out, Channel::Surface, 0, 16), 1.0);
        for h in 10..EL_CELLS {
            for w in 0..AZ_CELLS {
                assert_eq!(at(&out, Channel::Surface, h, w), 0.0);
            }
        }
    }

    /// The closer object wins a cell.
    #[test]
    fn closest_object_wins() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        f.add_plane(&sensor, -Vec3::Z, 2.0, SeenKind::Net);
        f.add_sphere(
            &sensor,
            Vec3::new(0.0, 0.0, 1.0),
            0.15,
            SeenKind::ChasePartner,
        );
        assert_eq!(f.kind_at(9, 16), Some(SeenKind::ChasePartner));
        assert_eq!(f.kind_at(9, 14), Some(SeenKind::Net));
    }

    #[test]
    fn an_obstacle_ahead_is_seen_as_obstacle() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        let sphere = Obstacle::Sphere {
            center: Vec3::new(0.0, -2.0, 2.0),
            radius: 0.5,
        };
        f.add_obstacle(&sensor, Vec3::new(0.0, -2.0, 0.0), Mat3::IDENTITY, &sphere);
        assert_eq!(f.kind_at(9, 16), Some(SeenKind::Obstacle));
        let mut out = vec![0.0; FRAME_LEN];
        f.write(&mut out);
        let c = sensor.cell_direction(9, 16);
        let t = sphere.ray_cast(Vec3::new(0.0, -2.0, 0.0), c, 3.0).unwrap();
        assert!((at(&out, Channel::Proximity, 9, 16) - (1.0 - t / 3.0)).abs() < 1e-6);
    }

    #[test]
    fn fast_atan2_is_close() {
        for k in 0..3600 {
            let t = (k as f32 * 0.1 - 180.0).to_radians();
            let (y, x) = (t.sin() * 2.5, t.cos() * 2.5);
            assert!((fast_atan2(y, x) - y.atan2(x)).abs() < 1e-5, "{t}");
        }
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
    }

    #[test]
    fn frames_stack_oldest_first() {
        let mut stack = vec![0.0; STACKED_LEN];
        for value in 1..=4 {
            push_frame(&mut stack).fill(value as f32);
        }
        assert_eq!(stack[0], 2.0);
        assert_eq!(stack[FRAME_LEN], 3.0);
        assert_eq!(stack[2 * FRAME_LEN], 4.0);
        reset_stack(&mut stack).fill(9.0);
        assert_eq!(
            (stack[0], stack[FRAME_LEN], stack[2 * FRAME_LEN]),
            (0.0, 0.0, 9.0)
        );
    }

    /// The byte stacks shift the same way, a frame being 1,360 bytes.
    #[test]
    fn byte_stacks_shift_by_frame_bytes() {
        let mut stack = vec![0u8; STACK * FRAME_BYTES];
        for value in 1..=4u8 {
            push_frame(&mut stack).fill(value);
        }
        assert_eq!(
            (stack[0], stack[FRAME_BYTES], stack[2 * FRAME_BYTES]),
            (2, 3, 4)
        );
        reset_stack(&mut stack).fill(9);
        assert_eq!(
            (stack[0], stack[FRAME_BYTES - 1], stack[2 * FRAME_BYTES]),
            (0, 0, 9)
        );
    }

    /// A fish, a nearer chase partner, a net 2 m ahead and the surface in a
    /// 3 m frame: the bytes written directly are the floats quantised.
    #[test]
    fn byte_frames_are_the_quantised_floats() {
        let sensor = GridSensor::new();
        let mut f = Frame::new(3.0);
        f.add_plane(&sensor, -Vec3::Z, 2.0, SeenKind::Net);
        f.add_sphere(&sensor, Vec3::new(0.3, 0.0, 1.0), 0.15, SeenKind::Fish);
        f.add_sphere(
            &sensor,
            Vec3::new(-0.3, 0.1, 0.6),
            0.1,
            SeenKind::ChasePartner,
        );
        f.add_plane(&sensor, -Vec3::Y, 0.5, SeenKind::Surface);
        let mut floats = vec![0.0; FRAME_LEN];
        f.write(&mut floats);
        let mut expected = vec![0u8; FRAME_BYTES];
        crate::frames::quantise(&floats, &mut expected);
        let mut bytes = vec![7u8; FRAME_BYTES];
        f.write_bytes(&mut bytes);
        assert_eq!(bytes, expected);
        // Cell (9, 16)'s centre ray (−5°, +4.5°) meets the net 2 m ahead at
        // 2 / (cos 5° cos 4.5°) = 2.0139 m: 1 − 2.0139/3 = 0.3287 → round(83.8) = 84.
        let c = 9 * AZ_CELLS + 16;
        assert_eq!((bytes[c], bytes[CELLS + c]), (84, SeenKind::Net as u8));
        assert!(bytes[CELLS..].contains(&(SeenKind::ChasePartner as u8)));
        assert!(bytes[CELLS..].contains(&(SeenKind::Fish as u8)));
    }

    /// Drawn nearest first, a batch still gives each cell the nearest sphere
    /// and, between spheres at the same distance, the first in the batch.
    #[test]
    fn the_nearest_and_then_the_first_sphere_wins() {
        let sensor = GridSensor::new();
        let ahead = Vec3::new(0.0, 0.0, 1.0);
        let draw = |spheres: &[(Vec3, f32, SeenKind)]| {
            let mut batch = SphereBatch::new();
            for &(rel, r, kind) in spheres {
                batch.push(rel, r, kind);
            }
            let mut f = Frame::new(3.0);
            f.add_spheres(&sensor, &batch);
            f
        };
        let (h, w) = sensor.cell_of(ahead).unwrap();
        // A far large sphere first, a near small one after: the centre cell is the near one's.
        let f = draw(&[
            (ahead * 2.0, 1.5, SeenKind::Fish),
            (ahead * 0.5, 0.05, SeenKind::ChasePartner),
        ]);
        assert_eq!(f.kind_at(h, w), Some(SeenKind::ChasePartner));
        assert_eq!(f.dist[h * AZ_CELLS + w], 0.5);
        // The far one still covers the cells around it.
        assert_eq!(f.kind_at(h, w + 2), Some(SeenKind::Fish));
        // Two spheres at one place: the first in the batch wins, in either order.
        for (first, second) in [
            (SeenKind::Fish, SeenKind::ChasePartner),
            (SeenKind::ChasePartner, SeenKind::Fish),
        ] {
            let f = draw(&[(ahead, 0.3, first), (ahead, 0.3, second)]);
            assert!(
                covered(&f)
                    .iter()
                    .all(|&(h, w)| f.kind_at(h, w) == Some(first))
            );
        }
    }

    /// The bounded search marks exactly the cells a brute-force test of all
    /// 680 cells marks, for any direction, distance and radius.
    mod brute_force {
        use super::*;
        use proptest::prelude::*;

        fn reference(
            sensor: &GridSensor,
            rel: Vec3,
            radius: f32,
            range: f32,
        ) -> Vec<(usize, usize)> {
            let d = rel.length();
            if d >= range || d <= 1e-6 {
                return vec![];
            }
            let dir = rel / d;
            let cos_alpha = (1.0 - (radius / d).min(1.0).powi(2)).max(0.0).sqrt();
            let centre = sensor.cell_of(dir);
            let mut v = vec![];
            for h in 0..EL_CELLS {
                for w in 0..AZ_CELLS {
                    if sensor.cell_direction(h, w).dot(dir) >= cos_alpha || centre == Some((h, w)) {
                        v.push((h, w));
                    }
                }
            }
            v
        }

        /// The frame of `spheres` by testing every cell against every sphere
        /// with `add_spheres`' own float operations: per cell the nearest
        /// sphere covering it (the first of equals), covering meaning its centre
        /// cell or a cell centre within the angular radius.
        fn every_cell(sensor: &GridSensor, spheres: &[(Vec3, f32)], range: f32) -> Vec<f32> {
            let limit = AZ_LIMIT_DEG.to_radians();
            let step = AZ_STEP_DEG.to_radians();
            let mut dist = vec![range; CELLS];
            for &(p, r) in spheres {
                let d2 = p.x * p.x + p.y * p.y + p.z * p.z;
                if !(d2 < range * range && d2 > 1e-12) {
                    continue;
                }
                let di = d2.max(1e-12).sqrt();
                let inv = 1.0 / di;
                let (ux, uy, uz) = (p.x * inv, p.y * inv, p.z * inv);
                let s = (r / di).min(1.0);
                let c = (1.0 - s * s).max(0.0).sqrt();
                let az = fast_atan2(-ux, uz);
                let centre = (az.abs() < limit).then(|| {
                    let h: usize = sensor
                        .row_floor_sin
                        .iter()
                        .map(|&e| (uy < e) as usize)
                        .sum();
                    let w = ((az + limit) / step).clamp(0.0, (AZ_CELLS - 1) as f32) as usize;
                    h.min(EL_CELLS - 1) * AZ_CELLS + w
                });
                for (cell, best) in dist.iter_mut().enumerate() {
                    let cos = sensor.dx[cell] * ux + sensor.dy[cell] * uy + sensor.dz[cell] * uz;
                    if (cos >= c || centre == Some(cell)) && di < *best {
                        *best = di;
                    }
                }
            }
            dist
        }

        proptest! {
            /// The candidate bounds (cell centres, with their slack) drop no cell
            /// the exact test would take: the frame is, bit for bit, that of
            /// testing every cell — far, tiny, near, polar and wrapping spheres.
            #[test]
            fn the_bounds_keep_every_cell_the_test_takes(
                spheres in prop::collection::vec(
                    (-180.0f32..180.0, -90.0f32..90.0, 0.02f32..3.0, prop_oneof![0.0f32..0.02, 0.0f32..0.3, 0.0f32..2.0]),
                    1..120,
                )
            ) {
                let sensor = GridSensor::new();
                let rel: Vec<(Vec3, f32)> = spheres
                    .iter()
                    .map(|&(az, el, d, r)| (direction(az.to_radians(), el.to_radians()) * d, r))
                    .collect();
                let mut f = Frame::new(3.0);
                let mut batch = SphereBatch::new();
                for &(p, r) in &rel {
                    batch.push(p, r, SeenKind::Fish);
                }
                f.add_spheres(&sensor, &batch);
                prop_assert_eq!(&f.dist[..], &every_cell(&sensor, &rel, 3.0)[..]);
            }

            /// A batch gives exactly the frame of the same spheres added one by one.
            #[test]
            fn a_batch_equals_spheres_one_by_one(
                spheres in prop::collection::vec((-1.6f32..1.6, -1.6f32..1.6, -1.6f32..1.6, 0.0f32..0.4, any::<bool>()), 1..150)
            ) {
                let sensor = GridSensor::new();
                let (mut one, mut many) = (Frame::new(1.5), Frame::new(1.5));
                let mut batch = SphereBatch::new();
                for &(x, y, z, r, partner) in &spheres {
                    let kind = if partner { SeenKind::ChasePartner } else { SeenKind::Fish };
                    one.add_sphere(&sensor, Vec3::new(x, y, z), r, kind);
                    if batch.push(Vec3::new(x, y, z), r, kind) {
                        many.add_spheres(&sensor, &batch);
                        batch.clear();
                    }
                }
                many.add_spheres(&sensor, &batch);
                prop_assert_eq!(&one.dist[..], &many.dist[..]);
                prop_assert_eq!(&one.kind[..], &many.kind[..]);
            }

            #[test]
            fn add_sphere_matches_brute_force(
                az in -180.0f32..180.0, el in -90.0f32..90.0, d in 0.05f32..2.9, r in 0.0f32..1.5
            ) {
                let sensor = GridSensor::new();
                let rel = direction(az.to_radians(), el.to_radians()) * d;
                let mut f = Frame::new(3.0);
                f.add_sphere(&sensor, rel, r, SeenKind::Fish);
                let want = reference(&sensor, rel, r, 3.0);
                // Cells on the exact angular boundary may differ by rounding: allow none
                // except where the reference dot product is within 1e-5 of cos α.
                let got = covered(&f);
                let dir = rel.normalize();
                let cos_alpha = (1.0 - (r / d).min(1.0).powi(2)).max(0.0).sqrt();
                for cell in got.iter().filter(|c| !want.contains(c)).chain(want.iter().filter(|c| !got.contains(c))) {
                    let dot = sensor.cell_direction(cell.0, cell.1).dot(dir);
                    prop_assert!((dot - cos_alpha).abs() < 1e-5, "cell {:?} differs (dot {}, cos α {})", cell, dot, cos_alpha);
                }
            }
        }
    }
}
