//! A uniform spatial grid (cell list) for neighbour queries.
//!
//! Built by counting sort every time positions change: `O(N)` with no
//! allocation after construction. Within a cell the entries are in ascending
//! index order and cells are visited in a fixed order, so every query visits
//! its candidates in the same order whatever the thread count — sums over
//! neighbours come out bit-identical.

use glam::Vec3;

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

    /// Re-file all items at `positions` (length must equal the capacity).
    pub fn rebuild(&mut self, positions: &[Vec3]) {
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
        for i in 0..positions.len() {
            let c = self.cell_of[i] as usize;
            let slot = self.cell_start[c] as usize;
            self.entries[slot] = i as u32;
            self.cell_start[c] += 1;
        }
        for c in (1..self.cell_start.len()).rev() {
            self.cell_start[c] = self.cell_start[c - 1];
        }
        self.cell_start[0] = 0;
    }

    /// Calls `f(j)` for every item filed in a cell overlapping the cube of
    /// half-edge `radius` around `p` — a superset of the items within `radius`;
    /// callers check the exact distance.
    #[inline]
    pub fn for_each_candidate(&self, p: Vec3, radius: f32, mut f: impl FnMut(usize)) {
        let lo = self.coord(p - Vec3::splat(radius));
        let hi = self.coord(p + Vec3::splat(radius));
        for cz in lo[2]..=hi[2] {
            for cy in lo[1]..=hi[1] {
                let row = self.index([0, cy, cz]);
                let start = self.cell_start[row + lo[0]] as usize;
                let end = self.cell_start[row + hi[0] + 1] as usize;
                // Cells of one x-row are contiguous in `entries`.
                for &j in &self.entries[start..end] {
                    f(j as usize);
                }
            }
        }
    }
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
        grid.rebuild(&pts);
        for (i, &p) in pts.iter().enumerate().step_by(7) {
            let r = 0.9;
            let mut got = Vec::new();
            grid.for_each_candidate(p, r, |j| {
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
        grid.rebuild(&pts);
        let mut seen = vec![];
        grid.for_each_candidate(Vec3::new(1.0, 0.0, 0.0), 0.1, |j| seen.push(j));
        assert_eq!(seen, vec![0]);
    }
}
