//! Light and temperature in the water column and the vertical responses they
//! cause (SPEC §3; thesis Eqs. 4.1–4.3).
//!
//! The responses are unitless magnitudes applied in BL/s along ±y: positive
//! means "swim up", negative "swim down".

/// Light at depth `d` (m) by Beer–Lambert, Eq. 4.1: `I = I0 · exp(−a·d)`.
#[inline]
pub fn light_at_depth(i0: f32, attenuation: f32, depth: f32) -> f32 {
    i0 * (-attenuation * depth.max(0.0)).exp()
}

/// Two-layer temperature (SPEC §3): `T_surf` falling 1 °C over the first metre,
/// constant below.
#[inline]
pub fn temperature_at_depth(t_surf: f32, depth: f32) -> f32 {
    t_surf - depth.clamp(0.0, 1.0)
}

/// The response to a value `x` outside a preferred band `[lo, hi]`, with
/// steepness `steep_lo < lo` and `steep_hi > hi` (Eqs. 4.2 and 4.3):
/// `(lo − x)/(lo − steep_lo)` up when `x ≤ lo`, `(x − hi)/(steep_hi − hi)`
/// down when `x ≥ hi`, else 0. Returned signed, positive up.
#[inline]
pub fn band_response(x: f32, lo: f32, hi: f32, steep_lo: f32, steep_hi: f32) -> f32 {
    if x <= lo {
        (lo - x) / (lo - steep_lo)
    } else if x >= hi {
        -(x - hi) / (steep_hi - hi)
    } else {
        0.0
    }
}

/// `Δv_light` (Eq. 4.2), positive up, BL/s.
#[inline]
pub fn light_response(i: f32, lpref: f32, hpref: f32, lsteep: f32, hsteep: f32) -> f32 {
    band_response(i, lpref, hpref, lsteep, hsteep)
}

/// `Δv_temp` (Eq. 4.3), positive up, BL/s.
#[inline]
pub fn temperature_response(t: f32, lpref: f32, hpref: f32, lsteep: f32, hsteep: f32) -> f32 {
    band_response(t, lpref, hpref, lsteep, hsteep)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Onmaehama at noon (I0 = 519.69, a = 1.5), coho with I_hpref = 7:
    /// at 1 m, I = 519.69 e^−1.5 = 115.96 PAR, above the band, so
    /// Δv_light = −(115.96 − 7)/(1000 − 7) = −0.10973 (down).
    #[test]
    fn coho_is_pushed_down_near_the_bright_surface() {
        let i = light_at_depth(519.69, 1.5, 1.0);
        assert!((i - 115.958).abs() < 1e-2, "{i}");
        let dv = light_response(i, 3.0, 7.0, -20.0, 1000.0);
        assert!((dv + 0.109726).abs() < 1e-5, "{dv}");
    }

    /// At 4 m, I = 519.69 e^−6 = 1.288 PAR, below I_lpref = 3:
    /// Δv_light = (3 − 1.288)/(3 + 20) = 0.07443 (up).
    #[test]
    fn coho_is_pulled_up_in_the_dark_deep() {
        let i = light_at_depth(519.69, 1.5, 4.0);
        assert!((i - 1.28823).abs() < 1e-4, "{i}");
        let dv = light_response(i, 3.0, 7.0, -20.0, 1000.0);
        assert!((dv - 0.074425).abs() < 1e-5, "{dv}");
        // Inside the band: no response (I at 3 m = 5.77 PAR ∈ [3, 7]).
        assert_eq!(
            light_response(light_at_depth(519.69, 1.5, 3.0), 3.0, 7.0, -20.0, 1000.0),
            0.0
        );
    }

    /// Night: I = 0 ≤ I_lpref, so every fish rises with (I_lpref − 0)/(I_lpref + 20).
    #[test]
    fn at_night_fish_rise() {
        let dv = light_response(light_at_depth(0.0, 1.5, 2.0), 5.75, 368.0, -20.0, 1000.0);
        assert!((dv - 5.75 / 25.75).abs() < 1e-6);
    }

    /// Onmaehama water (T_surf 8.3 °C), coho prefers 8–9 °C:
    /// at 0.2 m T = 8.1 (in band, 0); at 0.5 m T = 7.8 → (8 − 7.8)/(8 + 60) = 0.0029412 up;
    /// below 1 m T = 7.3 → 0.7/68 = 0.0102941 up.
    #[test]
    fn temperature_two_layers_and_coho_response() {
        assert!((temperature_at_depth(8.3, 0.2) - 8.1).abs() < 1e-6);
        assert!((temperature_at_depth(8.3, 3.0) - 7.3).abs() < 1e-6);
        assert_eq!(
            temperature_response(temperature_at_depth(8.3, 0.2), 8.0, 9.0, -60.0, 80.0),
            0.0
        );
        let dv = temperature_response(temperature_at_depth(8.3, 0.5), 8.0, 9.0, -60.0, 80.0);
        assert!((dv - 0.0029412).abs() < 1e-6, "{dv}");
        let dv = temperature_response(temperature_at_depth(8.3, 4.0), 8.0, 9.0, -60.0, 80.0);
        assert!((dv - 0.0102941).abs() < 1e-6, "{dv}");
    }

    /// Too warm: 30 °C for seabream (20–28) → −(30 − 28)/(80 − 28) = −0.0384615 (down).
    #[test]
    fn too_warm_pushes_down() {
        let dv = temperature_response(30.0, 20.0, 28.0, -60.0, 80.0);
        assert!((dv + 0.0384615).abs() < 1e-6);
    }
}
