//! Water optics (thesis Appendix A.2, SPEC §10) and the light that enters the
//! water (the sun of SPEC §3).
//!
//! Three colour channels stand for the wavelengths 650 nm (R), 550 nm (G) and
//! 450 nm (B).
//!
//! # Attenuation (Eq. A.1)
//! `ac = ac_water + c_chl·ac_chl + c_sed·ac_sed` (1/m per channel), each term
//! absorption plus scattering:
//! - water: absorption of pure water, Pope & Fry (1997): 0.340, 0.0565,
//!   0.00922 /m; scattering of sea water `0.0017·(550/λ)^4.3` (Kopelevich as
//!   given by Mobley 1994, *Light and Water*, p. 119).
//! - chlorophyll (per mg/m³): phytoplankton absorption read from Bricaud et al.
//!   (1998) near Chl = 1 mg/m³, 0.010, 0.007, 0.036 m²/mg, linearised as Eq. A.1
//!   does; particle scattering of Gordon & Morel (1983), `b(550) = 0.30·Chl^0.62`,
//!   linearised over 1–9 mg/m³ to 0.12 m²/mg, times `550/λ`. Blue is
//!   attenuated most, then red, then green (the thesis' §4.4.4 observation).
//! - sediment (per g/m³): mineral absorption 0.041·exp(−0.0123·(λ − 443)) m²/g and
//!   scattering 0.5·(555/λ)^0.4 m²/g (Babin et al. 2003).
//!
//! # Scattering (Eq. A.2)
//! The volume scattering function is Kopelevich's two-component model as
//! given by Mobley (1994): `β(ψ, λ) = β_w + v_s·β_s*(ψ)·(550/λ)^1.7 + v_l·β_l*(ψ)·(550/λ)^0.3`
//! with `b_s* = 1.34` and `b_l* = 0.312` /m per ppm (the thesis prints 500 nm
//! as the reference wavelength; Mobley's is 550 nm). The Kopelevich particles
//! add their scattering `b_s + b_l` to the beam attenuation, so the extinction
//! along a ray is `c = ac + b_s + b_l`. Sediment scatters like Kopelevich's
//! small (mineral) particles and chlorophyll-bearing cells like his large
//! (biological) ones.
//!
//! Documented simplification: instead of Kopelevich's tabulated angular shapes
//! (which the thesis picked "by visual inspection"), the particle phase
//! functions are Henyey–Greenstein with `g = 0.80` (small, broad) and `g = 0.95`
//! (large, strongly forward); pure water has Morel's (1974)
//! `0.06225·(1 + 0.835·cos²ψ)`. As in the thesis, each phase function is
//! normalised by its numerically integrated (trapezoid) total.
//!
//! # Light in the water
//! Single scattering of the refracted sun beam and of the diffuse sky light.
//! Both fall with depth by Beer–Lambert, `E(d) = E(0)·exp(−K·d)` (the law of
//! SPEC §3), with a per-channel diffuse attenuation `K = (a + b_b)/μ̄_d`,
//! `μ̄_d = 0.8` (Kirk 1984), from the same water that colours the view, so
//! colours stay consistent when the water is randomised. (The site's single
//! PAR coefficient `a` of SPEC §3 still drives the fish; Onmaehama's 1.5 /m
//! would need more sediment than the 0–5 g/m³ range allows.)
//!
//! Along a view ray from depth `d0` in direction `v` the in-scattered
//! radiance up to distance `t` has a closed form because the source term
//! varies as `exp(K·v_y·s)`: `S = J0·(1 − exp(−(c − K·v_y)·t))/(c − K·v_y)`,
//! `J0 = E_beam(d0)·β(ψ_sun) + E_diff(d0)·β_diff(v)`. A surface of radiance
//! `L` at distance `t` arrives as `L·exp(−c·t) + S`.

use deepfoids_env::sun::SunPlace;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;
use std::sync::OnceLock;

/// Wavelength of each channel (nm).
pub const WAVELENGTHS_NM: [f32; 3] = [650.0, 550.0, 450.0];
/// Absorption of pure water (1/m), Pope & Fry (1997), at 650/550/450 nm.
pub const A_WATER: Vec3 = Vec3::new(0.340, 0.0565, 0.00922);
/// Phytoplankton absorption per unit chlorophyll (m²/mg), Bricaud et al. (1998) near 1 mg/m³.
pub const A_CHL: Vec3 = Vec3::new(0.010, 0.007, 0.036);
/// Particle scattering per unit chlorophyll at 550 nm (m²/mg), Gordon & Morel (1983) linearised.
pub const B_CHL_550: f32 = 0.12;
/// Mineral absorption at 443 nm (m²/g) and its spectral slope (1/nm), Babin et al. (2003).
pub const A_SED_443: f32 = 0.041;
pub const A_SED_SLOPE: f32 = 0.0123;
/// Mineral scattering at 555 nm (m²/g), Babin et al. (2003).
pub const B_SED_555: f32 = 0.5;
/// Kopelevich's scattering of sea water at 550 nm (1/m), exponent 4.3 (Mobley 1994).
pub const B_WATER_550: f32 = 0.0017;
/// Kopelevich's small- and large-particle scattering per ppm at 550 nm (1/m).
pub const B_SMALL: f32 = 1.34;
pub const B_LARGE: f32 = 0.312;
/// Henyey–Greenstein asymmetry of the small and large particles (documented simplification).
pub const G_SMALL: f32 = 0.80;
pub const G_LARGE: f32 = 0.95;
/// Mean cosine of the downwelling light in `K = (a + b_b)/μ̄_d` (Kirk 1984).
pub const MU_D: f32 = 0.8;
/// Refractive index of sea water.
pub const N_WATER: f32 = 1.34;

/// What is in the water. The defaults are a moderately clear coastal cage.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaterParams {
    /// Chlorophyll concentration (mg/m³); randomised in [0, 9]; default 1.
    pub chlorophyll: f32,
    /// Suspended sediment (g/m³); randomised in [0, 5]; default 0.5.
    pub sediment: f32,
    /// Kopelevich small-particle volume concentration `v_s` (ppm); randomised in [0, 4]; default 0.05.
    pub small_particles: f32,
    /// Kopelevich large-particle volume concentration `v_l` (ppm); randomised in [0, 4]; default 0.1.
    pub large_particles: f32,
}

impl Default for WaterParams {
    fn default() -> Self {
        Self {
            chlorophyll: 1.0,
            sediment: 0.5,
            small_particles: 0.05,
            large_particles: 0.1,
        }
    }
}

fn per_channel(f: impl Fn(f32) -> f32) -> Vec3 {
    Vec3::new(
        f(WAVELENGTHS_NM[0]),
        f(WAVELENGTHS_NM[1]),
        f(WAVELENGTHS_NM[2]),
    )
}

/// Morel's (1974) phase function of pure water (1/sr), unnormalised shape.
pub fn phase_water_shape(cos: f32) -> f32 {
    0.06225 * (1.0 + 0.835 * cos * cos)
}

/// Henyey–Greenstein phase function (1/sr), normalised analytically.
pub fn phase_hg(g: f32, cos: f32) -> f32 {
    let d = (1.0 + g * g - 2.0 * g * cos).max(1e-12);
    (1.0 - g * g) / (4.0 * PI * d * d.sqrt())
}

/// `2π ∫ f(cos ψ) sin ψ dψ` over `[lo, hi]` (radians) by the trapezoid rule
/// on `n` intervals, the thesis' normalisation of a VSF into a phase function.
pub fn integrate_sphere(f: impl Fn(f32) -> f32, lo: f32, hi: f32, n: usize) -> f32 {
    let h = (hi - lo) / n as f32;
    let g = |i: usize| {
        let psi = lo + h * i as f32;
        f(psi.cos()) * psi.sin()
    };
    let inner: f32 = (1..n).map(g).sum();
    2.0 * PI * h * (0.5 * g(0) + inner + 0.5 * g(n))
}

/// Entries of the diffuse phase table over `cos θ_v ∈ [−1, 1]`.
const CONE_TABLE: usize = 129;

/// The phase functions of water, small and large particles averaged over the
/// diffuse light's directions, per unit horizontal irradiance.
///
/// Below a flat surface the sky's light arrives from within Snell's cone,
/// half-angle `θc = asin(1/n)`, with uniform radiance `L`, so the horizontal
/// irradiance is `E = L·π·sin²θc` and the light scattered into a view ray
/// `v` is `J = L·∫_cone p(u·v) dω_u = E·P(v_y)` with
/// `P(v_y) = ∫_cone p(u·v) dω_u / (π·sin²θc)` (u runs over the directions
/// the light comes from). Tabulated once over `v_y` by the midpoint rule;
/// unlike the phase value at the zenith it has no sharp forward spike, so
/// the sky does not draw a bright spot straight above a camera.
struct ConePhases {
    water: [f32; CONE_TABLE],
    small: [f32; CONE_TABLE],
    large: [f32; CONE_TABLE],
}

fn cone_phases() -> &'static ConePhases {
    static TABLE: OnceLock<ConePhases> = OnceLock::new();
    TABLE.get_or_init(|| {
        let water_norm = 1.0 / integrate_sphere(phase_water_shape, 0.0, PI, 720);
        let theta_c = (1.0 / N_WATER).asin();
        let (n_theta, n_phi) = (160, 180);
        let (dt, dp) = (theta_c / n_theta as f32, PI / n_phi as f32);
        let norm = PI * theta_c.sin().powi(2);
        let mut t = ConePhases {
            water: [0.0; CONE_TABLE],
            small: [0.0; CONE_TABLE],
            large: [0.0; CONE_TABLE],
        };
        for k in 0..CONE_TABLE {
            let mu = -1.0 + 2.0 * k as f32 / (CONE_TABLE - 1) as f32;
            let sv = (1.0 - mu * mu).max(0.0).sqrt();
            let (mut w, mut s, mut l) = (0.0f64, 0.0f64, 0.0f64);
            for i in 0..n_theta {
                let th = (i as f32 + 0.5) * dt;
                // Both halves of the azimuth: the integrand is even in φ.
                let dw = (2.0 * th.sin() * dt * dp) as f64;
                for j in 0..n_phi {
                    let ph = (j as f32 + 0.5) * dp;
                    let c = th.cos() * mu + th.sin() * sv * ph.cos();
                    w += (phase_water_shape(c) * water_norm) as f64 * dw;
                    s += phase_hg(G_SMALL, c) as f64 * dw;
                    l += phase_hg(G_LARGE, c) as f64 * dw;
                }
            }
            t.water[k] = (w / norm as f64) as f32;
            t.small[k] = (s / norm as f64) as f32;
            t.large[k] = (l / norm as f64) as f32;
        }
        t
    })
}

/// Linear interpolation of a cone table at `cos θ_v = mu`.
fn cone_lookup(table: &[f32; CONE_TABLE], mu: f32) -> f32 {
    let x = (mu.clamp(-1.0, 1.0) + 1.0) * 0.5 * (CONE_TABLE - 1) as f32;
    let i = (x as usize).min(CONE_TABLE - 2);
    let f = x - i as f32;
    table[i] * (1.0 - f) + table[i + 1] * f
}

/// The optical properties of one frame's water, per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Water {
    pub params: WaterParams,
    /// Eq. A.1 attenuation `ac` (1/m).
    pub ac: Vec3,
    /// Absorption (1/m).
    pub a: Vec3,
    /// Scattering with the water phase function (1/m).
    pub b_water: Vec3,
    /// Scattering with the small-particle phase function: Kopelevich small + sediment (1/m).
    pub b_small: Vec3,
    /// Scattering with the large-particle phase function: Kopelevich large + chlorophyll (1/m).
    pub b_large: Vec3,
    /// Extinction along a ray, `ac + b_s + b_l` (1/m); equals `ac` when scattering is off.
    pub c: Vec3,
    /// Diffuse attenuation of the downwelling light `K` (1/m).
    pub k: Vec3,
    /// Whether in-scattering is rendered.
    pub scattering: bool,
    /// Normalisation of Morel's water shape (so its integral is 1).
    water_norm: f32,
}

impl Water {
    /// Coefficients for `params`; with `scattering` off there is no
    /// in-scattered light and the extinction is Eq. A.1's `ac` alone.
    pub fn new(params: WaterParams, scattering: bool) -> Self {
        let p = params;
        let b_w = per_channel(|l| B_WATER_550 * (550.0 / l).powf(4.3));
        let b_chl = per_channel(|l| B_CHL_550 * 550.0 / l);
        let a_sed = per_channel(|l| A_SED_443 * (-A_SED_SLOPE * (l - 443.0)).exp());
        let b_sed = per_channel(|l| B_SED_555 * (555.0 / l).powf(0.4));
        let ac_water = A_WATER + b_w;
        let ac_chl = A_CHL + b_chl;
        let ac_sed = a_sed + b_sed;
        let ac = ac_water + p.chlorophyll * ac_chl + p.sediment * ac_sed;
        let kop_s = per_channel(|l| B_SMALL * (550.0 / l).powf(1.7)) * p.small_particles;
        let kop_l = per_channel(|l| B_LARGE * (550.0 / l).powf(0.3)) * p.large_particles;
        let a = A_WATER + p.chlorophyll * A_CHL + p.sediment * a_sed;
        let b_small = kop_s + p.sediment * b_sed;
        let b_large = kop_l + p.chlorophyll * b_chl;
        let water_norm = 1.0 / integrate_sphere(phase_water_shape, 0.0, PI, 720);
        let back = |f: &dyn Fn(f32) -> f32| integrate_sphere(f, PI / 2.0, PI, 720);
        let bb_w = back(&|c| phase_water_shape(c) * water_norm);
        let bb_s = back(&|c| phase_hg(G_SMALL, c));
        let bb_l = back(&|c| phase_hg(G_LARGE, c));
        let bb = b_w * bb_w + b_small * bb_s + b_large * bb_l;
        let c = if scattering { ac + kop_s + kop_l } else { ac };
        Self {
            params,
            ac,
            a,
            b_water: b_w,
            b_small,
            b_large,
            c,
            k: (a + bb) / MU_D,
            scattering,
            water_norm,
        }
    }

    /// The volume scattering function `β(ψ)` per channel (1/(m·sr)), Eq. A.2.
    pub fn vsf(&self, cos_psi: f32) -> Vec3 {
        self.b_water * (phase_water_shape(cos_psi) * self.water_norm)
            + self.b_small * phase_hg(G_SMALL, cos_psi)
            + self.b_large * phase_hg(G_LARGE, cos_psi)
    }

    /// Scattering of the diffuse sky light into a ray whose direction has
    /// vertical component `v_y`, per unit horizontal irradiance (1/(m·sr));
    /// see [`ConePhases`].
    pub fn vsf_diffuse(&self, v_y: f32) -> Vec3 {
        let t = cone_phases();
        self.b_water * cone_lookup(&t.water, v_y)
            + self.b_small * cone_lookup(&t.small, v_y)
            + self.b_large * cone_lookup(&t.large, v_y)
    }

    /// Beam transmittance over `t` metres, `exp(−c·t)`.
    pub fn transmittance(&self, t: f32) -> Vec3 {
        (-self.c * t).exp()
    }
}

/// [`Light::inscatter`] once the ray's source `j0` (at the camera) and
/// `x = c − K·v_y` are known: `j0·(1 − exp(−x·t))/x` per channel. Both
/// depend on the ray alone, so a renderer keeps them per pixel.
pub fn inscatter_along(j0: Vec3, x: Vec3, t: f32) -> Vec3 {
    let f = |x: f32| {
        if x.abs() < 1e-5 {
            t
        } else {
            (1.0 - (-x * t).exp()) / x
        }
    };
    j0 * Vec3::new(f(x.x), f(x.y), f(x.z))
}

/// The sun and sky of one frame, as they are below the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Solar elevation above the horizon (degrees).
    pub sun_elevation_deg: f32,
    pub sun_azimuth_deg: f32,
    /// Surface light relative to the site's noon maximum, `I0(t)/I_max` (SPEC §3).
    pub surface_fraction: f32,
    /// Unit vector towards the sun in air (world frame: +x east, +y up, +z south).
    pub sun_dir_air: Vec3,
    /// Unit vector towards the sun below the surface (refracted).
    pub sun_dir_water: Vec3,
    /// Irradiance of the refracted beam just below the surface, on a plane normal to it.
    pub e_beam0: Vec3,
    /// Diffuse (sky) irradiance just below the surface, on a horizontal plane.
    pub e_diff0: Vec3,
    /// Sky radiance seen through Snell's window.
    pub sky_radiance: Vec3,
    /// Sun colour in air (for the glare in Snell's window).
    pub sun_colour: Vec3,
}

/// Fresnel reflectance of unpolarised light from air into water at incidence `theta_i` (rad).
pub(crate) fn fresnel_air_water(theta_i: f32) -> f32 {
    let st = theta_i.sin() / N_WATER;
    let ct = (1.0 - st * st).max(0.0).sqrt();
    let ci = theta_i.cos();
    let rs = ((ci - N_WATER * ct) / (ci + N_WATER * ct)).powi(2);
    let rp = ((ct - N_WATER * ci) / (ct + N_WATER * ci)).powi(2);
    0.5 * (rs + rp)
}

impl Light {
    /// The sun of SPEC §3 at a place and local time. Irradiances are relative:
    /// 1 = the site's surface light at solar noon of the date.
    pub fn new(place: SunPlace, year: i32, month: u32, day: u32, hours: f64) -> Self {
        let pos = place.position(year, month, day, hours);
        let frac = place.surface_light(1.0, year, month, day, hours) as f32;
        let el = pos.elevation_deg as f32;
        let az = (pos.azimuth_deg as f32).to_radians();
        let elr = el.to_radians();
        // Compass azimuth clockwise from north; north is −z, east +x.
        let sun_dir_air = Vec3::new(az.sin() * elr.cos(), elr.sin(), -az.cos() * elr.cos());
        let zen = (PI / 2.0 - elr).clamp(0.0, PI / 2.0);
        let zen_w = (zen.sin() / N_WATER).asin();
        let horiz = Vec3::new(sun_dir_air.x, 0.0, sun_dir_air.z).normalize_or(Vec3::X);
        let sun_dir_water = horiz * zen_w.sin() + Vec3::Y * zen_w.cos();
        // Colour of the direct sun after the air mass (Kasten & Young 1989),
        // Rayleigh-like optical depths beyond the zenith path; white at the zenith.
        let m = 1.0 / (elr.max(0.0).sin() + 0.50572 * (el.max(0.0) + 6.07995).powf(-1.6364));
        let tau = Vec3::new(0.04, 0.08, 0.17);
        let sun_colour = (-tau * (m - 1.0).max(0.0)).exp();
        // Share of diffuse sky light grows as the sun sinks.
        let f_diff = 0.2 + 0.7 * (-el.max(0.0) / 10.0).exp();
        let sky_colour = Vec3::new(0.62, 0.80, 1.0);
        let t_dir = 1.0 - fresnel_air_water(zen);
        let t_diff = 0.93;
        let e_dir_h = frac * (1.0 - f_diff) * t_dir * sun_colour;
        let e_beam0 = e_dir_h / zen_w.cos().max(0.05);
        let e_diff0 = frac * f_diff * t_diff * sky_colour;
        Self {
            sun_elevation_deg: el,
            sun_azimuth_deg: pos.azimuth_deg as f32,
            surface_fraction: frac,
            sun_dir_air,
            sun_dir_water,
            e_beam0,
            e_diff0,
            sky_radiance: frac * f_diff * sky_colour / PI,
            sun_colour: frac * (1.0 - f_diff) * sun_colour,
        }
    }

    /// Beam and diffuse irradiance at depth `d` (m).
    pub fn at_depth(&self, water: &Water, d: f32) -> (Vec3, Vec3) {
        let f = (-water.k * d.max(0.0)).exp();
        (self.e_beam0 * f, self.e_diff0 * f)
    }

    /// Irradiance on a horizontal plane at depth `d` (the exposure reference).
    pub fn horizontal_irradiance(&self, water: &Water, d: f32) -> Vec3 {
        let (b, diff) = self.at_depth(water, d);
        b * self.sun_dir_water.y + diff
    }

    /// In-scattering source `J` (radiance per metre) for a ray in direction `v`
    /// at depth `d`.
    pub fn source(&self, water: &Water, d: f32, v: Vec3) -> Vec3 {
        if !water.scattering {
            return Vec3::ZERO;
        }
        let (beam, diff) = self.at_depth(water, d);
        // ψ is the angle between the light's travel (−s) and the scattered
        // direction towards the camera (−v): cos ψ = s·v.
        let beta_sun = water.vsf(self.sun_dir_water.dot(v));
        // Diffuse light comes from within Snell's cone.
        beam * beta_sun + diff * water.vsf_diffuse(v.y)
    }

    /// In-scattered radiance along `t` metres of a ray from depth `d0` in
    /// direction `v` (closed form, see the module doc).
    pub fn inscatter(&self, water: &Water, d0: f32, v: Vec3, t: f32) -> Vec3 {
        if !water.scattering {
            return Vec3::ZERO;
        }
        inscatter_along(self.source(water, d0, v), water.c - water.k * v.y, t)
    }

    /// What a camera at depth `d0` sees of a surface of radiance `l` at
    /// distance `t` along `v`: `l·exp(−c·t) + S(t)`.
    pub fn composite(&self, water: &Water, l: Vec3, d0: f32, v: Vec3, t: f32) -> Vec3 {
        l * water.transmittance(t) + self.inscatter(water, d0, v, t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noon_place() -> SunPlace {
        SunPlace {
            latitude_deg: 38.465,
            longitude_deg: 141.480,
            utc_offset_hours: 9.0,
        }
    }

    /// Eq. A.1 by hand for chl 2 mg/m³, sediment 1 g/m³ at 550 nm:
    /// water 0.0565 + 0.0017; chl 2·(0.007 + 0.12); sediment
    /// 0.041·e^(−0.0123·107) + 0.5·(555/550)^0.4.
    #[test]
    fn attenuation_follows_eq_a1() {
        let w = Water::new(
            WaterParams {
                chlorophyll: 2.0,
                sediment: 1.0,
                small_particles: 0.0,
                large_particles: 0.0,
            },
            false,
        );
        let sed = 0.041 * (-0.0123f32 * 107.0).exp() + 0.5 * (555.0f32 / 550.0).powf(0.4);
        let expect = 0.0565 + 0.0017 + 2.0 * (0.007 + 0.12) + sed;
        assert!((w.ac.y - expect).abs() < 1e-5, "{} vs {expect}", w.ac.y);
        assert_eq!(w.c, w.ac);
        // Chlorophyll absorbs blue most, then red, then green (thesis §4.4.4).
        let chl = Water::new(
            WaterParams {
                chlorophyll: 1.0,
                sediment: 0.0,
                small_particles: 0.0,
                large_particles: 0.0,
            },
            false,
        );
        let d = chl.a
            - Water::new(
                WaterParams {
                    chlorophyll: 0.0,
                    ..chl.params
                },
                false,
            )
            .a;
        assert!(d.z > d.x && d.x > d.y, "{d}");
    }

    /// Kopelevich: 1 ppm of small particles scatters 1.34 /m at 550 nm and
    /// 1.34·(550/450)^1.7 /m at 450 nm; the extinction includes it.
    #[test]
    fn kopelevich_scattering_coefficients() {
        let p = WaterParams {
            chlorophyll: 0.0,
            sediment: 0.0,
            small_particles: 1.0,
            large_particles: 2.0,
        };
        let w = Water::new(p, true);
        assert!((w.b_small.y - 1.34).abs() < 1e-5);
        assert!((w.b_small.z - 1.34 * (550.0f32 / 450.0).powf(1.7)).abs() < 1e-4);
        assert!((w.b_large.y - 0.624).abs() < 1e-5);
        assert!((w.c.y - (w.ac.y + 1.34 + 0.624)).abs() < 1e-5);
    }

    /// Each phase function integrates to 1 over the sphere (trapezoid, as the thesis does).
    #[test]
    fn phase_functions_are_normalised() {
        for g in [G_SMALL, G_LARGE] {
            let s = integrate_sphere(|c| phase_hg(g, c), 0.0, PI, 20_000);
            assert!((s - 1.0).abs() < 2e-3, "g {g}: {s}");
        }
        let w = Water::new(WaterParams::default(), true);
        let total = integrate_sphere(|c| w.vsf(c).y, 0.0, PI, 20_000);
        let b = w.b_water.y + w.b_small.y + w.b_large.y;
        assert!((total - b).abs() < 2e-3 * b, "{total} vs {b}");
    }

    /// The diffuse phase table conserves energy: over all view directions
    /// `2π ∫ P(μ) dμ = Ω_cone/(π sin²θc) = 2(1 − cos θc)/sin²θc` (1.2007 for
    /// n = 1.34) for every phase function; water's nearly isotropic shape
    /// gives about the same value everywhere, the large particles' forward
    /// lobe is brightest straight up and bounded by its point value.
    #[test]
    fn diffuse_phase_table_conserves_energy() {
        let tc = (1.0 / N_WATER).asin();
        let want = 2.0 * (1.0 - tc.cos()) / tc.sin().powi(2);
        assert!((want - 1.2007).abs() < 1e-3, "{want}");
        let t = cone_phases();
        for (name, tab) in [
            ("water", &t.water),
            ("small", &t.small),
            ("large", &t.large),
        ] {
            let total = 2.0 * PI * integrate_lin(|mu| cone_lookup(tab, mu), -1.0, 1.0, 20_000);
            assert!(
                (total - want).abs() < 5e-3 * want,
                "{name}: {total} vs {want}"
            );
        }
        let mid = cone_lookup(&t.water, 0.0);
        assert!((cone_lookup(&t.water, 1.0) / mid - 1.0).abs() < 0.6);
        assert!(cone_lookup(&t.large, 1.0) > 20.0 * cone_lookup(&t.large, -0.5));
        assert!(cone_lookup(&t.large, 1.0) < phase_hg(G_LARGE, 1.0));
    }

    fn integrate_lin(f: impl Fn(f32) -> f32, lo: f32, hi: f32, n: usize) -> f32 {
        let h = (hi - lo) / n as f32;
        (0..n).map(|i| f(lo + (i as f32 + 0.5) * h) * h).sum()
    }

    /// With scattering off, a white surface (radiance 1) at distance d appears
    /// as exp(−ac·d) per channel.
    #[test]
    fn without_scattering_a_white_surface_fades_by_beer_lambert() {
        let w = Water::new(WaterParams::default(), false);
        let light = Light::new(noon_place(), 2021, 3, 15, 11.5);
        for d in [0.5f32, 2.0, 5.0] {
            let got = light.composite(&w, Vec3::ONE, 2.0, Vec3::new(0.6, 0.0, 0.8), d);
            let expect = Vec3::new(
                (-w.ac.x * d).exp(),
                (-w.ac.y * d).exp(),
                (-w.ac.z * d).exp(),
            );
            assert!(
                (got - expect).abs().max_element() < 1e-6,
                "{got} vs {expect}"
            );
        }
    }

    /// The closed-form in-scatter equals a numerical integral of the source
    /// along a slanted ray, and tends to J/(c − K v_y) far away.
    #[test]
    fn inscatter_closed_form_matches_numerical_integral() {
        let w = Water::new(WaterParams::default(), true);
        let light = Light::new(noon_place(), 2021, 3, 15, 11.5);
        let v = Vec3::new(0.3, 0.5, -0.8).normalize();
        let (d0, t) = (3.0, 4.0);
        let n = 4000;
        let h = t / n as f32;
        let mut num = Vec3::ZERO;
        for i in 0..n {
            let s = (i as f32 + 0.5) * h;
            num += light.source(&w, d0 - s * v.y, v) * (-w.c * s).exp() * h;
        }
        let closed = light.inscatter(&w, d0, v, t);
        assert!(
            ((closed - num) / num).abs().max_element() < 1e-3,
            "{closed} vs {num}"
        );
    }

    #[test]
    fn night_is_dark_and_noon_is_bright() {
        let night = Light::new(noon_place(), 2021, 3, 15, 23.0);
        assert_eq!(night.e_beam0, Vec3::ZERO);
        assert_eq!(night.e_diff0, Vec3::ZERO);
        let noon = Light::new(noon_place(), 2021, 3, 15, 11.7);
        assert!(noon.surface_fraction > 0.99);
        // The sun is in the south at noon (+z) and the refracted beam is steeper.
        assert!(noon.sun_dir_air.z > 0.5);
        assert!(noon.sun_dir_water.y > noon.sun_dir_air.y);
        let evening = Light::new(noon_place(), 2021, 3, 15, 17.3);
        assert!(evening.surface_fraction < 0.3 && evening.surface_fraction > 0.0);
        // The low sun is redder.
        let c = evening.sun_colour / evening.sun_colour.max_element();
        assert!(c.x > c.z, "{c}");
    }
}
