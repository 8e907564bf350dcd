//! The sun: solar elevation from place, date and time, and the surface light
//! `I0(t)` it gives (SPEC §3). The dataset renderer uses the same sun.
//!
//! Solar position follows NOAA's "General Solar Position Calculations"
//! (fractional-year Fourier series for the equation of time and the
//! declination), accurate to a fraction of a degree — far below the
//! uncertainty of the field light data.
//!
//! Surface light: `I0(t) = I_max · sin(elev(t)) / sin(elev_noon)` while the sun
//! is up and 0 at night, so it equals the site maximum at solar noon of the
//! scene's date (SPEC §3).

use std::f64::consts::PI;

/// Days in `month` (1–12) of `year` (Gregorian).
pub fn days_in_month(year: i32, month: u32) -> u32 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if is_leap(year) => 29,
        2 => 28,
        _ => 0,
    }
}

fn is_leap(year: i32) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

/// Day of the year, 1 for January 1st.
pub fn day_of_year(year: i32, month: u32, day: u32) -> u32 {
    (1..month).map(|m| days_in_month(year, m)).sum::<u32>() + day
}

/// Where and when the sun is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunPlace {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub utc_offset_hours: f64,
}

/// Position of the sun in the sky.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunPosition {
    /// Angle above the horizon (degrees); negative at night.
    pub elevation_deg: f64,
    /// Compass azimuth, clockwise from north (degrees).
    pub azimuth_deg: f64,
}

struct Orbit {
    eq_time_min: f64,
    declination: f64,
}

fn orbit(year: i32, doy: u32, hours: f64) -> Orbit {
    let days = if is_leap(year) { 366.0 } else { 365.0 };
    let g = 2.0 * PI / days * (doy as f64 - 1.0 + (hours - 12.0) / 24.0);
    let eq_time_min = 229.18
        * (0.000075 + 0.001868 * g.cos()
            - 0.032077 * g.sin()
            - 0.014615 * (2.0 * g).cos()
            - 0.040849 * (2.0 * g).sin());
    let declination = 0.006918 - 0.399912 * g.cos() + 0.070257 * g.sin()
        - 0.006758 * (2.0 * g).cos()
        + 0.000907 * (2.0 * g).sin()
        - 0.002697 * (3.0 * g).cos()
        + 0.00148 * (3.0 * g).sin();
    Orbit {
        eq_time_min,
        declination,
    }
}

impl SunPlace {
    /// Sun position at local clock time `hours` (0–24, may exceed 24 to roll over) on a date.
    pub fn position(&self, year: i32, month: u32, day: u32, hours: f64) -> SunPosition {
        let doy = day_of_year(year, month, day) + (hours / 24.0).floor() as u32;
        let hours = hours.rem_euclid(24.0);
        let o = orbit(year, doy, hours);
        let time_offset = o.eq_time_min + 4.0 * self.longitude_deg - 60.0 * self.utc_offset_hours;
        let true_solar_min = hours * 60.0 + time_offset;
        let hour_angle = (true_solar_min / 4.0 - 180.0).to_radians();
        let lat = self.latitude_deg.to_radians();
        let cos_zenith = (lat.sin() * o.declination.sin()
            + lat.cos() * o.declination.cos() * hour_angle.cos())
        .clamp(-1.0, 1.0);
        let zenith = cos_zenith.acos();
        // Azimuth clockwise from north.
        let sin_z = zenith.sin().max(1e-9);
        let cos_az =
            ((lat.sin() * cos_zenith - o.declination.sin()) / (lat.cos() * sin_z)).clamp(-1.0, 1.0);
        let az = 180.0 - cos_az.acos().to_degrees();
        let azimuth_deg = if hour_angle > 0.0 { 360.0 - az } else { az };
        SunPosition {
            elevation_deg: 90.0 - zenith.to_degrees(),
            azimuth_deg: azimuth_deg.rem_euclid(360.0),
        }
    }

    /// Local clock time of solar noon on a date (hours).
    pub fn solar_noon_hours(&self, year: i32, month: u32, day: u32) -> f64 {
        let o = orbit(year, day_of_year(year, month, day), 12.0);
        (720.0 - 4.0 * self.longitude_deg - o.eq_time_min + 60.0 * self.utc_offset_hours) / 60.0
    }

    /// Surface light `I0` (PAR) at local time `hours`: `i_max` at solar noon of
    /// the date, proportional to the sine of the elevation, 0 at night.
    pub fn surface_light(&self, i_max: f64, year: i32, month: u32, day: u32, hours: f64) -> f64 {
        let elev = self.position(year, month, day, hours).elevation_deg;
        if elev <= 0.0 {
            return 0.0;
        }
        let noon = self.solar_noon_hours(year, month, day);
        let elev_noon = self.position(year, month, day, noon).elevation_deg;
        if elev_noon <= 0.0 {
            return 0.0;
        }
        i_max * elev.to_radians().sin() / elev_noon.to_radians().sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONMAEHAMA: SunPlace = SunPlace {
        latitude_deg: 38.465,
        longitude_deg: 141.480,
        utc_offset_hours: 9.0,
    };

    #[test]
    fn day_of_year_counts_leap_days() {
        assert_eq!(day_of_year(2021, 3, 15), 31 + 28 + 15);
        assert_eq!(day_of_year(2024, 3, 15), 31 + 29 + 15);
        assert_eq!(day_of_year(2021, 12, 31), 365);
    }

    /// Equinox-ish check: on 2021-03-20 the declination is ≈ 0, so the noon
    /// elevation is ≈ 90° − latitude = 51.5°; solar noon at 141.48° E in UTC+9 is
    /// ≈ 12:00 − 4 min/° × (141.48 − 135)° + 7 min (equation of time) ≈ 11:41.
    #[test]
    fn noon_elevation_at_the_equinox_is_ninety_minus_latitude() {
        let noon = ONMAEHAMA.solar_noon_hours(2021, 3, 20);
        assert!(
            (noon - (12.0 - 25.9 / 60.0 + 7.5 / 60.0)).abs() < 3.0 / 60.0,
            "noon at {noon}"
        );
        let e = ONMAEHAMA.position(2021, 3, 20, noon).elevation_deg;
        assert!((e - (90.0 - 38.465)).abs() < 0.6, "elevation {e}");
        let az = ONMAEHAMA.position(2021, 3, 20, noon).azimuth_deg;
        assert!((az - 180.0).abs() < 0.5, "azimuth {az}");
    }

    #[test]
    fn light_is_maximal_at_noon_and_zero_at_night() {
        let (y, m, d) = (2021, 3, 15);
        let noon = ONMAEHAMA.solar_noon_hours(y, m, d);
        assert!((ONMAEHAMA.surface_light(519.69, y, m, d, noon) - 519.69).abs() < 1e-6);
        assert_eq!(ONMAEHAMA.surface_light(519.69, y, m, d, 0.0), 0.0);
        assert_eq!(ONMAEHAMA.surface_light(519.69, y, m, d, 22.0), 0.0);
        let eleven = ONMAEHAMA.surface_light(519.69, y, m, d, 11.0);
        assert!(eleven > 450.0 && eleven < 519.69, "{eleven}");
        // Morning is dimmer than late morning.
        assert!(ONMAEHAMA.surface_light(519.69, y, m, d, 7.0) < eleven);
    }
}
