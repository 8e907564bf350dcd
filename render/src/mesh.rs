//! Fish meshes generated in code: a body of revolution with elliptical cross
//! sections, a forked tail fin, a dorsal and an anal fin, proportions and
//! colours per species, in body lengths (scaled by each fish's BL).
//!
//! Local frame: `+z` forward (the nose at `z = +0.5`, the tail tip at
//! `z = −0.5`), `+y` up (the back), `+x` to the fish's side. The body is
//! closed, so its back faces are culled; the fins are two-sided.
//!
//! Tail beat (optional): a travelling wave of lateral displacement
//! `Δx = A·e(s)·sin(φ − 2π s)`, `s` the distance from the nose in BL,
//! `e(s) = ((s − 0.25)/0.75)²` behind the first quarter; the caller drives
//! the phase `φ` and the amplitude `A` (swimming vs hovering).

use glam::Vec3;

/// Body proportions and colours of one species.
#[derive(Clone, Debug, PartialEq)]
pub struct FishStyle {
    /// Species id (`coho`, `yellowtail`, `seabream`, …).
    pub species: String,
    /// Largest body depth / BL.
    pub depth: f32,
    /// Largest body width / BL.
    pub width: f32,
    /// Back colour, linear RGB albedo.
    pub back: Vec3,
    /// Belly colour.
    pub belly: Vec3,
    /// Colour of a lateral stripe, if the species has one (yellowtail).
    pub stripe: Option<Vec3>,
    /// Fin colour.
    pub fins: Vec3,
    /// Dorsal fin from/to (s, BL from the nose) and its height (× depth).
    pub dorsal: (f32, f32, f32),
}

impl FishStyle {
    /// The style of a species from its config values: `collider_bl = [w, h, l]`
    /// gives the proportions (the collider wraps the body and fins), `colour`
    /// the back; the belly is silvery, except for the red seabream's pale pink;
    /// the yellowtail amberjack gets its yellow lateral stripe.
    pub fn for_species(species: &str, collider_bl: [f32; 3], colour: [f32; 3]) -> Self {
        let c = Vec3::from(colour);
        let silver = Vec3::new(0.80, 0.80, 0.78);
        let (belly, stripe, fins, dorsal) = match species {
            "seabream" => (c.lerp(Vec3::ONE, 0.45), None, c * 0.85, (0.22, 0.72, 0.35)),
            "yellowtail" => (
                silver,
                Some(Vec3::new(0.85, 0.70, 0.12)),
                Vec3::new(0.75, 0.62, 0.15),
                (0.30, 0.55, 0.25),
            ),
            _ => (silver, None, c * 0.7, (0.33, 0.48, 0.35)),
        };
        Self {
            species: species.to_string(),
            depth: collider_bl[1] * 0.85,
            width: collider_bl[0] * 0.9,
            back: c * 0.65,
            belly,
            stripe,
            fins,
            dorsal,
        }
    }
}

/// A mesh in body lengths.
#[derive(Clone, Debug)]
pub struct FishMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    /// Albedo per vertex (linear RGB).
    pub albedo: Vec<Vec3>,
    /// Distance from the nose (BL) per vertex, for the tail beat.
    pub s: Vec<f32>,
    /// Fin vertices are lit from both sides.
    pub two_sided: Vec<bool>,
    pub triangles: Vec<[u32; 3]>,
    /// Triangles from this index on are fins (two-sided, never culled).
    pub first_fin: usize,
}

/// Where the body ends and the tail fin begins (BL from the nose).
const PEDUNCLE: f32 = 0.84;

/// Body thickness profile along `s` (0 at the nose), 1 at its widest.
fn profile(s: f32) -> f32 {
    // s^0.5 (1 − s)^0.8 peaks at s = 0.5/1.3 with value 0.4196.
    (s.max(0.0).sqrt() * (1.0 - s).max(0.0).powf(0.8)) / 0.4196
}

impl FishMesh {
    /// Build the mesh of a species: `rings` cross sections of `segments` vertices.
    pub fn new(style: &FishStyle, rings: usize, segments: usize) -> Self {
        let mut m = FishMesh {
            positions: Vec::new(),
            normals: Vec::new(),
            albedo: Vec::new(),
            s: Vec::new(),
            two_sided: Vec::new(),
            triangles: Vec::new(),
            first_fin: 0,
        };
        let (hh, hw) = (style.depth / 2.0, style.width / 2.0);
        let colour = |y_rel: f32| -> Vec3 {
            let t = ((y_rel + 0.2) / 0.8).clamp(0.0, 1.0);
            let t = t * t * (3.0 - 2.0 * t);
            let base = style.belly.lerp(style.back, t);
            match style.stripe {
                Some(s) if (y_rel - 0.05).abs() < 0.13 => s,
                _ => base,
            }
        };
        let push = |m: &mut FishMesh, p: Vec3, s: f32, albedo: Vec3, fin: bool| -> u32 {
            m.positions.push(p);
            m.normals.push(Vec3::ZERO);
            m.albedo.push(albedo);
            m.s.push(s);
            m.two_sided.push(fin);
            (m.positions.len() - 1) as u32
        };
        // Nose.
        let nose = push(&mut m, Vec3::new(0.0, 0.0, 0.5), 0.0, style.back, false);
        let mut ring_start = Vec::with_capacity(rings);
        for i in 1..=rings {
            let s = PEDUNCLE * (i as f32 / rings as f32).powf(1.3);
            let r = profile(s);
            ring_start.push(m.positions.len() as u32);
            for j in 0..segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                let (sn, cs) = phi.sin_cos();
                let p = Vec3::new(hw * r * cs, hh * r * sn, 0.5 - s);
                push(&mut m, p, s, colour(sn), false);
            }
        }
        let tail_centre = push(
            &mut m,
            Vec3::new(0.0, 0.0, 0.5 - PEDUNCLE),
            PEDUNCLE,
            style.back,
            false,
        );
        let seg = segments as u32;
        // Triangles wind counter-clockwise seen from outside.
        for j in 0..seg {
            let a = ring_start[0] + j;
            let b = ring_start[0] + (j + 1) % seg;
            m.triangles.push([nose, a, b]);
        }
        for i in 0..rings - 1 {
            let (r0, r1) = (ring_start[i], ring_start[i + 1]);
            for j in 0..seg {
                let j1 = (j + 1) % seg;
                m.triangles.push([r0 + j, r1 + j, r0 + j1]);
                m.triangles.push([r0 + j1, r1 + j, r1 + j1]);
            }
        }
        let last = ring_start[rings - 1];
        for j in 0..seg {
            m.triangles
                .push([last + j, tail_centre, last + (j + 1) % seg]);
        }
        // Smooth normals: area-weighted face normals of the body.
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let n = (b - a).cross(c - a);
            for i in t {
                m.normals[*i as usize] += n;
            }
        }
        for n in &mut m.normals {
            *n = n.normalize_or(Vec3::Y);
        }

        // Fins, in the y–z plane, two-sided.
        m.first_fin = m.triangles.len();
        let fin = |m: &mut FishMesh, pts: &[(f32, f32)], tris: &[[usize; 3]]| {
            let idx: Vec<u32> = pts
                .iter()
                .map(|&(s, y)| {
                    let i = push(m, Vec3::new(0.0, y, 0.5 - s), s, style.fins, true);
                    m.normals[i as usize] = Vec3::X;
                    i
                })
                .collect();
            for t in tris {
                m.triangles.push(t.map(|k| idx[k]));
            }
        };
        let hp = hh * profile(PEDUNCLE) * 0.9;
        let ht = style.depth * 0.85;
        // Forked caudal fin: peduncle top/bottom, upper tip, notch, lower tip.
        fin(
            &mut m,
            &[
                (PEDUNCLE - 0.02, hp),
                (PEDUNCLE - 0.02, -hp),
                (1.0, ht / 2.0 + hp),
                (0.93, 0.0),
                (1.0, -ht / 2.0 - hp),
            ],
            &[[0, 2, 3], [0, 3, 1], [1, 3, 4]],
        );
        let (d0, d1, dh) = style.dorsal;
        let top = |s: f32| hh * profile(s) * 0.95;
        fin(
            &mut m,
            &[
                (d0, top(d0)),
                (d1, top(d1)),
                (d0 + 0.25 * (d1 - d0), top(d0) + dh * style.depth),
            ],
            &[[0, 2, 1]],
        );
        let bottom = |s: f32| -hh * profile(s) * 0.95;
        fin(
            &mut m,
            &[
                (0.62, bottom(0.62)),
                (0.76, bottom(0.76)),
                (0.66, bottom(0.66) - 0.18 * style.depth),
            ],
            &[[0, 2, 1]],
        );
        m
    }

    /// The default resolution: 14 rings of 14 vertices (≈ 400 triangles).
    pub fn standard(style: &FishStyle) -> Self {
        Self::new(style, 14, 14)
    }

    /// Vertex `i` displaced by the tail beat of amplitude `amp` (BL) at phase `phase`.
    #[inline]
    pub fn bent(&self, i: usize, amp: f32, phase: f32) -> Vec3 {
        let p = self.positions[i];
        let s = self.s[i];
        if amp == 0.0 || s <= 0.25 {
            return p;
        }
        let e = ((s - 0.25) / 0.75).powi(2);
        p + Vec3::X * (amp * e * (phase - std::f32::consts::TAU * s).sin())
    }
}

/// Tail-beat frequency (Hz) of a fish swimming at `speed_bl` BL/s, from
/// Bainbridge (1958), `U = L·(0.75 f − 1)/4`; at least 0.5 Hz (fin sculling
/// while hovering).
pub fn tail_beat_hz(speed_bl: f32) -> f32 {
    ((4.0 * speed_bl + 1.0) / 0.75).max(0.5)
}

/// Tail-beat amplitude at the tail tip (BL): 0.1 BL when swimming (0.2 BL
/// peak to peak, Bainbridge 1958), 0.03 BL when hovering below
/// `v_st = 0.3 BL/s` (the thesis' swim/hover states).
pub fn tail_beat_amplitude(speed_bl: f32) -> f32 {
    if speed_bl < 0.3 { 0.03 } else { 0.1 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesh_is_one_body_length_long_and_closed() {
        let style = FishStyle::for_species("coho", [0.12, 0.25, 1.0], [0.4, 0.5, 0.6]);
        let m = FishMesh::standard(&style);
        let (lo, hi) = m.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        assert!((hi.z - 0.5).abs() < 1e-6 && (lo.z + 0.5).abs() < 1e-6);
        // The body's widest point is the style's width.
        assert!(
            (hi.x * 2.0 - style.width).abs() < 0.01 * style.width,
            "{}",
            hi.x
        );
        assert!(m.triangles.len() > 300 && m.triangles.len() < 500);
        // Closed body: every edge of the body triangles is shared by exactly two.
        let mut edges = std::collections::HashMap::new();
        for t in &m.triangles[..m.first_fin] {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&n| n == 2));
        // Outward normals: the upper side's normals point up.
        let up = m
            .positions
            .iter()
            .zip(&m.normals)
            .zip(&m.two_sided)
            .filter(|((p, _), fin)| p.y > 0.05 && !**fin)
            .all(|((_, n), _)| n.y > 0.0);
        assert!(up);
    }

    #[test]
    fn tail_beat_moves_only_the_back() {
        let style = FishStyle::for_species("seabream", [0.14, 0.38, 1.0], [0.8, 0.4, 0.4]);
        let m = FishMesh::standard(&style);
        for i in 0..m.positions.len() {
            let d = m.bent(i, 0.1, 1.0) - m.positions[i];
            if m.s[i] <= 0.25 {
                assert_eq!(d, Vec3::ZERO);
            }
            assert!(d.x.abs() <= 0.1 + 1e-6 && d.y == 0.0 && d.z == 0.0);
        }
        assert!((tail_beat_hz(1.0) - 20.0 / 3.0).abs() < 1e-5);
    }
}
