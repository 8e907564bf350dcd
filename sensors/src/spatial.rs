//! A uniform spatial grid (cell list) for neighbour queries.
//!
//! Built by counting sort every time positions change: `O(N)` with no
//! allocation after construction. Within a cell the entries are in ascending
//! index order and cells are visited in a fixed order, so every query visits
//! its candidates in the same order whatever the thread count — sums over
//! neighbours come out bit-identical.

use glam::{Vec3, Vec4};

/// A uniform grid over an axis-aligned box, holding item indices by cell.
#[derive(Clone, Debug)]
pub struct SpatialGrid {
    origin: Vec3,
    inv_cell: f32,
    cell: f32,
    dims: [usize; 3],
    /// `cell_start[c]..cell_start[c + 1]` indexes `entries` for cell `c`.
    cell_start: Vec<u32>,
    entries: Vec<u32>,
    /// `(x, y, z, w)` of each entry, in entry order: candidates are read from
    /// contiguous memory; `w` is a per-item value the caller chose (a radius).
    points: Vec<Vec4>,
    cell_of: Vec<u32>,
}

impl SpatialGrid {
    /// A grid covering `min..max` with cubic cells of edge `cell` (m) for `capacity` items.
    ///
    /// Points outside the box are filed in the nearest border cell, so queries stay correct.
    pub fn new(min: Vec3, max: Vec3, cell: f32, capacity: usize) -> Self {
        assert!(
            cell > 0.0 && cell.is_finite(),
            "grid cell size must be positive"
        );
        let extent = (max - min).max(Vec3::splat(cell));
        let dims = [
            ((extent.x / cell).ceil() as usize).clamp(1, 256),
            ((extent.y / cell).ceil() as usize).clamp(1, 256),
            ((extent.z / cell).ceil() as usize).clamp(1, 256),
        ];
        let n_cells = dims[0] * dims[1] * dims[2];
        Self {
            origin: min,
            inv_cell: 1.0 / cell,
            cell,
            dims,
            cell_start: vec![0; n_cells + 1],
            entries: vec![0; capacity],
            points: vec![Vec4::ZERO; capacity],
            cell_of: vec![0; capacity],
        }
    }

    /// Edge length of a cell (m).
    pub fn cell_size(&self) -> f32 {
        self.cell
    }

    #[inline]
    fn coord(&self, p: Vec3) -> [usize; 3] {
        let q = (p - self.origin) * self.inv_cell;
        [
            (q.x.max(0.0) as usize).min(self.dims[0] - 1),
            (q.y.max(0.0) as usize).min(self.dims[1] - 1),
            (q.z.max(0.0) as usize).min(self.dims[2] - 1),
        ]
    }

    #[inline]
    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Re-file all items at `positions` (length must equal the capacity), each
    /// carrying `w[i]` (or 0 if `w` is empty) to the queries.
    pub fn rebuild(&mut self, positions: &[Vec3], w: &[f32]) {
        assert_eq!(
            positions.len(),
            self.entries.len(),
            "grid capacity mismatch"
        );
        self.cell_start.fill(0);
        for (i, &p) in positions.iter().enumerate() {
            let c = self.index(self.coord(p));
            self.cell_of[i] = c as u32;
            self.cell_start[c + 1] += 1;
        }
        for c in 0..self.cell_start.len() - 1 {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        // Scatter in index order; `cell_start[c]` walks forward and is restored below.
        for (i, &p) in positions.iter().enumerate() {
            let c = self.cell_of[i] as usize;
            let slot = self.cell_start[c] as usize;
            self.entries[slot] = i as u32;
            self.points[slot] = p.extend(w.get(i).copied().unwrap_or(0.0));
            self.cell_start[c] += 1;
        }
        for c in (1..self.cell_start.len()).rev() {
            self.cell_start[c] = self.cell_start[c - 1];
        }
        self.cell_start[0] = 0;
    }

    /// The items in the order the queries visit them (each cell's items
    /// together): `entries()[slot]` is the item at `slot`. Data the caller
    /// reads for each candidate can be laid out in this order
    /// ([`SpatialGrid::for_each_candidate_slot`]), so a query reads it
    /// contiguously instead of at scattered item indices.
    pub fn entries(&self) -> &[u32] {
        &self.entries
    }

    /// Calls `f(j)` for every item filed in a cell that intersects the ball of
    /// `radius` around `p` — a superset of the items within `radius`; callers
    /// check the exact distance. Rows of cells are clipped to the ball's
    /// cross-section, so about half the candidates of the bounding cube are visited.
    #[inline]
    pub fn for_each_candidate(&self, p: Vec3, radius: f32, mut f: impl FnMut(usize, Vec4)) {
        self.for_each_candidate_slot(p, radius, |_, j, q| f(j, q));
    }

    /// [`SpatialGrid::for_each_candidate`], also giving each candidate's slot
    /// in [`SpatialGrid::entries`]: `f(slot, j, q)`.
    #[inline]
    pub fn for_each_candidate_slot(
        &self,
        p: Vec3,
        radius: f32,
        mut f: impl FnMut(usize, usize, Vec4),
    ) {
        let lo = self.coord(p - Vec3::splat(radius));
        let hi = self.coord(p + Vec3::splat(radius));
        let r2 = radius * radius;
        let q = (p - self.origin) * self.inv_cell;
        for cz in lo[2]..=hi[2] {
            let dz = axis_gap(q.z, cz, self.dims[2]) * self.cell;
            for cy in lo[1]..=hi[1] {
                let dy = axis_gap(q.y, cy, self.dims[1]) * self.cell;
                let rest = r2 - dy * dy - dz * dz;
                if rest < 0.0 {
                    continue;
                }
                // The x-extent of the ball's cross-section in this row of cells.
                let rx = rest.sqrt();
                let x_lo = self.coord(Vec3::new(p.x - rx, p.y, p.z))[0].max(lo[0]);
                let x_hi = self.coord(Vec3::new(p.x + rx, p.y, p.z))[0].min(hi[0]);
                let row = self.index([0, cy, cz]);
                let start = self.cell_start[row + x_lo] as usize;
                let end = self.cell_start[row + x_hi + 1] as usize;
                // Cells of one x-row are contiguous in `entries`.
                for (slot, (&j, &q)) in self.entries[start..end]
                    .iter()
                    .zip(&self.points[start..end])
                    .enumerate()
                {
                    f(start + slot, j as usize, q);
                }
            }
        }
    }
}

/// Distance, in cells, from coordinate `q` (in cell units) to cell `c` along one
/// axis; border cells extend to infinity (they also hold points outside the box).
#[inline]
fn axis_gap(q: f32, c: usize, n: usize) -> f32 {
    let lo = if c == 0 { f32::NEG_INFINITY } else { c as f32 };
    let hi = if c + 1 == n {
        f32::INFINITY
    } else {
        (c + 1) as f32
    };
    (lo - q).max(q - hi).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force and the grid agree on who lies within the radius.
    #[test]
    fn grid_finds_exactly_the_brute_force_neighbours() {
        let mut pts = Vec::new();
        let mut s = 12345u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        for _ in 0..500 {
            pts.push(Vec3::new(
                next() * 6.0 - 3.0,
                -next() * 4.0,
                next() * 6.0 - 3.0,
            ));
        }
        let mut grid = SpatialGrid::new(
            Vec3::new(-3.0, -4.0, -3.0),
            Vec3::new(3.0, 0.0, 3.0),
            0.7,
            pts.len(),
        );
        let w: Vec<f32> = (0..pts.len()).map(|i| i as f32).collect();
        grid.rebuild(&pts, &w);
        for (i, &p) in pts.iter().enumerate().step_by(7) {
            let r = 0.9;
            let mut got = Vec::new();
            grid.for_each_candidate_slot(p, r, |slot, j, q| {
                assert_eq!(q, pts[j].extend(j as f32));
                assert_eq!(grid.entries()[slot] as usize, j);
                if j != i && pts[j].distance(p) < r {
                    got.push(j)
                }
            });
            got.sort();
            let want: Vec<usize> = (0..pts.len())
                .filter(|&j| j != i && pts[j].distance(p) < r)
                .collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn points_outside_the_box_are_still_found() {
        let pts = vec![Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.5, 0.5, 0.5)];
        let mut grid = SpatialGrid::new(Vec3::ZERO, Vec3::ONE, 0.25, 2);
        grid.rebuild(&pts, &[]);
        let mut seen = vec![];
        grid.for_each_candidate(Vec3::new(1.0, 0.0, 0.0), 0.1, |j, _| seen.push(j));
        assert_eq!(seen, vec![0]);
    }
}
