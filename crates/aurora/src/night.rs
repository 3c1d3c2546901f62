//! The night around the aurora: real stars for a site and a moment, and airglow.
//!
//! **Stars** come from the Hipparcos catalogue to visual magnitude 6 (5,044 stars, the
//! npm package d3-celestial's `stars.6.json`, turned into `data/stars.csv` by
//! `tools/stars/make_catalogue.py`). Each star's J2000 position is precessed to the
//! date (the annual rates of Meeus, *Astronomical Algorithms*, ch. 21: good to an
//! arcminute for a century), turned to the sky of the site by the local sidereal time
//! (GMST of IAU 1982, Meeus eq 12.4), dimmed by the atmosphere's extinction (0.2
//! magnitudes per airmass, a clear site's V band; airmass of Kasten & Young 1989) and
//! coloured as a blackbody at the temperature its B-V index gives (Ballesteros 2012).
//! A star of magnitude m gives 2.54e-6 · 10^(-0.4 m) lux at the eye.
//!
//! **Airglow** is the sky's own faint light, seen on every night: O(¹S) 557.7 nm from a
//! layer near 97 km (100-250 R at the zenith over the solar cycle; default 150),
//! O(¹D) 630.0 nm near 250 km (about 60 R), and the visible bands of OH's Meinel system
//! near 87 km ((6-1) at 650 nm and (7-2) at 695 nm, of order a hundred R each; the
//! rest of the system is infrared). Values from Roach & Gordon, *The Light of the Night
//! Sky* (1973) and Leinert et al. 1998 (A&AS 127, §8); the OH bands are the least
//! certain and can be set. A thin layer at height h seen at zenith angle z is brighter
//! by the van Rhijn factor 1/√(1 − (R/(R+h))² sin²z) (a longer path through it), and
//! dimmed on the way down by extinction, of which an extended glow gets about half back
//! as light scattered into the line of sight from the rest of the sky (a rough
//! allowance, not a radiative-transfer model): the glow brightens towards the horizon
//! and stays bright down to it, so a landscape stands out against it, as in
//! photographs of aurora.

use std::sync::OnceLock;

use glam::{DVec3, Vec3};
use phenomena_core::validate::Issues;
use serde::{Deserialize, Serialize};

/// Earth's mean radius, km.
const EARTH_RADIUS_KM: f64 = 6371.0;
/// Extinction, magnitudes per airmass (V band, clear site).
const EXTINCTION_MAG_PER_AIRMASS: f64 = 0.2;

/// One catalogue star.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Star {
    /// Hipparcos number.
    pub hip: u32,
    /// Right ascension, degrees (J2000).
    pub ra_deg: f64,
    /// Declination, degrees (J2000).
    pub dec_deg: f64,
    /// Visual magnitude.
    pub vmag: f32,
    /// B-V colour index (0.6, the Sun's, where the catalogue has none).
    pub bv: f32,
}

/// The catalogue, brightest first.
pub fn catalogue() -> &'static [Star] {
    static STARS: OnceLock<Vec<Star>> = OnceLock::new();
    STARS.get_or_init(|| {
        include_str!("../data/stars.csv")
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
            .filter_map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                Some(Star {
                    hip: f.first()?.parse().ok()?,
                    ra_deg: f.get(1)?.parse().ok()?,
                    dec_deg: f.get(2)?.parse().ok()?,
                    vmag: f.get(3)?.parse().ok()?,
                    bv: f.get(4).and_then(|b| b.parse().ok()).unwrap_or(0.6),
                })
            })
            .collect()
    })
}

/// Where and when the sky is seen (`[render.sky.site]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Site {
    /// Geographic latitude, degrees north.
    pub latitude_deg: f64,
    /// Geographic longitude, degrees east.
    pub longitude_deg: f64,
    /// The moment of frame 0, UTC, as `YYYY-MM-DDTHH:MM:SSZ`; frames advance it by the
    /// frame time.
    pub utc: String,
}

impl Default for Site {
    /// Tromsø, Norway, under the auroral oval, on a January evening.
    fn default() -> Self {
        Self { latitude_deg: 69.65, longitude_deg: 18.96, utc: "2027-01-15T21:00:00Z".into() }
    }
}

impl Site {
    /// Every problem, fields under `prefix`.
    pub fn validate(&self, i: &mut Issues, prefix: &str) {
        i.range(&format!("{prefix}.latitude_deg"), self.latitude_deg, -90.0..=90.0);
        i.range(&format!("{prefix}.longitude_deg"), self.longitude_deg, -180.0..=360.0);
        if let Err(e) = julian_day(&self.utc) {
            i.push(format!("{prefix}.utc"), format!("{:?}", self.utc), e);
        }
    }

    /// Julian day of frame 0 (the text has been validated; a bad one reads as J2000).
    pub fn julian_day(&self) -> f64 {
        julian_day(&self.utc).unwrap_or(J2000)
    }
}

/// JD of 2000-01-01 12:00 TT (taken as UTC: the difference is under a minute).
const J2000: f64 = 2_451_545.0;

/// Julian day of `YYYY-MM-DDTHH:MM:SS[.fff]Z` (Meeus ch. 7, Gregorian calendar).
pub fn julian_day(utc: &str) -> Result<f64, String> {
    let bad = || "a UTC time such as \"2027-01-15T21:00:00Z\" (years 1800-2200)".to_string();
    let s = utc.strip_suffix('Z').ok_or_else(bad)?;
    let (date, time) = s.split_once('T').ok_or_else(bad)?;
    let d: Vec<&str> = date.split('-').collect();
    let t: Vec<&str> = time.split(':').collect();
    if d.len() != 3 || t.len() != 3 {
        return Err(bad());
    }
    let (y, m, day): (i32, u32, u32) = (
        d[0].parse().map_err(|_| bad())?,
        d[1].parse().map_err(|_| bad())?,
        d[2].parse().map_err(|_| bad())?,
    );
    let (hh, mm): (u32, u32) = (t[0].parse().map_err(|_| bad())?, t[1].parse().map_err(|_| bad())?);
    let ss: f64 = t[2].parse().map_err(|_| bad())?;
    let days_in_month = match m {
        2 if (y % 4 == 0 && y % 100 != 0) || y % 400 == 0 => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    };
    if !(1800..=2200).contains(&y)
        || !(1..=12).contains(&m)
        || !(1..=days_in_month).contains(&day)
        || hh > 23
        || mm > 59
        || !(0.0..60.0).contains(&ss)
    {
        return Err(bad());
    }
    let (y, m) = if m <= 2 { (y - 1, m + 12) } else { (y, m) };
    let a = (f64::from(y) / 100.0).floor();
    let b = 2.0 - a + (a / 4.0).floor();
    let day_fraction = (f64::from(hh) + f64::from(mm) / 60.0 + ss / 3600.0) / 24.0;
    Ok((365.25 * f64::from(y + 4716)).floor() + (30.6001 * f64::from(m + 1)).floor() + f64::from(day) + b
        - 1524.5
        + day_fraction)
}

/// Greenwich mean sidereal time at Julian day `jd`, degrees (Meeus eq 12.4).
pub fn gmst_deg(jd: f64) -> f64 {
    let t = (jd - J2000) / 36_525.0;
    (280.460_618_37 + 360.985_647_366_29 * (jd - J2000) + 0.000_387_933 * t * t - t * t * t / 38_710_000.0)
        .rem_euclid(360.0)
}

/// A star's direction in the sky view's world frame at Julian day `jd` for an observer
/// at `latitude_deg`, `longitude_deg`: y up, z north and x west (the frame is
/// right-handed with y up, so a camera looking north has +x on its left and east,
/// −x, on its right, as an observer facing north does).
pub fn direction(star: &Star, jd: f64, latitude_deg: f64, longitude_deg: f64) -> DVec3 {
    let (ra, dec) = precess(star.ra_deg, star.dec_deg, (jd - J2000) / 365.25);
    let hour_angle = (gmst_deg(jd) + longitude_deg - ra).to_radians();
    let (dec, lat) = (dec.to_radians(), latitude_deg.to_radians());
    let east = -dec.cos() * hour_angle.sin();
    let north = dec.sin() * lat.cos() - dec.cos() * hour_angle.cos() * lat.sin();
    let up = dec.sin() * lat.sin() + dec.cos() * hour_angle.cos() * lat.cos();
    DVec3::new(-east, up, north)
}

/// J2000 (ra, dec) in degrees moved by `years` of general precession (Meeus eq 21.1:
/// m = 3.075 s, n = 1.336 s = 20.04″ per year).
fn precess(ra_deg: f64, dec_deg: f64, years: f64) -> (f64, f64) {
    let (ra, dec) = (ra_deg.to_radians(), dec_deg.to_radians());
    let m_deg = 3.075 / 240.0;
    let n_deg = 1.336 / 240.0;
    let d_ra = (m_deg + n_deg * ra.sin() * dec.tan().clamp(-1e3, 1e3)) * years;
    let d_dec = 20.04 / 3600.0 * ra.cos() * years;
    (ra_deg + d_ra, dec_deg + d_dec)
}

/// Airmass at elevation `elevation_rad` (Kasten & Young 1989); infinite below the horizon.
pub fn airmass(elevation_rad: f64) -> f64 {
    let e = elevation_rad.to_degrees();
    if e <= -1.0 {
        return f64::INFINITY;
    }
    let e = e.max(0.0);
    1.0 / (e.to_radians().sin() + 0.50572 * (e + 6.07995).powf(-1.6364))
}

/// Fraction of a point source's light (a star's) that reaches the ground from elevation
/// `elevation_rad`.
pub fn transmission(elevation_rad: f64) -> f64 {
    10f64.powf(-0.4 * EXTINCTION_MAG_PER_AIRMASS * airmass(elevation_rad))
}

/// Effective temperature of a star of colour index `bv`, K (Ballesteros 2012, EPL 97).
pub fn temperature_k(bv: f32) -> f64 {
    let bv = f64::from(bv.clamp(-0.4, 2.0));
    4600.0 * (1.0 / (0.92 * bv + 1.7) + 1.0 / (0.92 * bv + 0.62))
}

/// Milky Way map: cells per row and rows ([`milky_way_level`]).
const MW_W: usize = 720;
const MW_H: usize = 360;

/// The Milky Way's outline levels (0-5) on a 0.5° grid of J2000 right ascension and
/// declination, from `data/milky_way.txt` (d3-celestial's `mw.json`, rasterised by
/// `tools/stars/make_milky_way.py`).
fn milky_way_map() -> &'static [u8] {
    static MAP: OnceLock<Vec<u8>> = OnceLock::new();
    MAP.get_or_init(|| {
        let mut map = Vec::with_capacity(MW_W * MW_H);
        for line in include_str!("../data/milky_way.txt").lines().filter(|l| !l.starts_with('#')) {
            for run in line.split_whitespace() {
                let (level, count) = run.split_once('*').unwrap_or(("0", "0"));
                let (level, count) = (level.parse().unwrap_or(0u8), count.parse().unwrap_or(0usize));
                map.extend(std::iter::repeat_n(level, count));
            }
        }
        map.resize(MW_W * MW_H, 0);
        map
    })
}

/// The Milky Way's level (0 outside, 5 in its brightest star clouds), interpolated
/// bilinearly, at J2000 right ascension and declination in degrees.
pub fn milky_way_level(ra_deg: f64, dec_deg: f64) -> f32 {
    let map = milky_way_map();
    let x = (ra_deg.rem_euclid(360.0) / 0.5 - 0.5).rem_euclid(MW_W as f64);
    let y = ((89.75 - dec_deg) / 0.5).clamp(0.0, (MW_H - 1) as f64);
    let (x0, y0) = (x.floor() as usize % MW_W, (y.floor() as usize).min(MW_H - 1));
    let (x1, y1) = ((x0 + 1) % MW_W, (y0 + 1).min(MW_H - 1));
    let (fx, fy) = ((x - x.floor()) as f32, (y - y.floor()) as f32);
    let at = |x: usize, y: usize| f32::from(map[y * MW_W + x]);
    let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
    let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Right ascension and declination, degrees, of world direction `d` (x west, y up,
/// z north: [`direction`]'s frame) at Julian day `jd` from `latitude_deg`,
/// `longitude_deg` (of the date: J2000 within the half degree precession has moved
/// them since).
pub fn equatorial(d: DVec3, jd: f64, latitude_deg: f64, longitude_deg: f64) -> (f64, f64) {
    let d = d.normalize();
    let (east, up, north) = (-d.x, d.y, d.z);
    let lat = latitude_deg.to_radians();
    let dec = (north * lat.cos() + up * lat.sin()).clamp(-1.0, 1.0).asin();
    let hour_angle = (-east).atan2(up * lat.cos() - north * lat.sin());
    ((gmst_deg(jd) + longitude_deg - hour_angle.to_degrees()).rem_euclid(360.0), dec.to_degrees())
}

/// Airglow brightness at the zenith, rayleighs (`[render.sky.airglow]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Airglow {
    /// O(¹S) 557.7 nm, emitted near 97 km.
    pub o557_r: f32,
    /// O(¹D) 630.0 nm, emitted near 250 km.
    pub o630_r: f32,
    /// OH Meinel (6-1) band, 650 nm, emitted near 87 km.
    pub oh650_r: f32,
    /// OH Meinel (7-2) band, 695 nm, emitted near 87 km.
    pub oh695_r: f32,
    /// The rest of the natural night sky at the zenith, V-band surface brightness,
    /// mag/arcsec²: integrated starlight, zodiacal light and the airglow's continuum,
    /// drawn as sunlight-coloured (a 5800 K blackbody). The whole dark sky is about
    /// 22-22.5 (0.17-0.11 mcd/m²; Leinert et al. 1998), of which the lines above are a
    /// sixth; the default, 22.5, is the darker end.
    pub continuum_mag_arcsec2: f32,
}

impl Default for Airglow {
    fn default() -> Self {
        Self { o557_r: 150.0, o630_r: 60.0, oh650_r: 100.0, oh695_r: 100.0, continuum_mag_arcsec2: 22.5 }
    }
}

impl Airglow {
    /// Every problem, fields under `prefix`.
    pub fn validate(&self, i: &mut Issues, prefix: &str) {
        for (name, v) in [
            ("o557_r", self.o557_r),
            ("o630_r", self.o630_r),
            ("oh650_r", self.oh650_r),
            ("oh695_r", self.oh695_r),
        ] {
            i.range(&format!("{prefix}.{name}"), v, 0.0..=1e6);
        }
        i.range(&format!("{prefix}.continuum_mag_arcsec2"), self.continuum_mag_arcsec2, 10.0..=40.0);
    }

    /// (wavelength nm, zenith rayleighs, layer height km) of each emission.
    pub fn layers(&self) -> [(f64, f64, f64); 4] {
        [
            (557.7, f64::from(self.o557_r), 97.0),
            (630.0, f64::from(self.o630_r), 250.0),
            (650.0, f64::from(self.oh650_r), 87.0),
            (695.0, f64::from(self.oh695_r), 87.0),
        ]
    }
}

/// Fraction of an extended glow's light seen from elevation `elevation_rad`: the
/// transmission plus half of what extinction removes, scattered back in from the rest
/// of the glowing sky (see the module documentation).
pub fn glow_transmission(elevation_rad: f64) -> f64 {
    let t = transmission(elevation_rad);
    t + 0.5 * (1.0 - t)
}

/// Luminance of the continuum, cd/m² (10.8e4 · 10^(−0.4 m) for m in V mag/arcsec²).
pub fn continuum_cd_m2(mag_arcsec2: f32) -> f64 {
    10.8e4 * 10f64.powf(-0.4 * f64::from(mag_arcsec2))
}

/// Van Rhijn factor of a thin layer at `height_km` seen at elevation `elevation_rad`.
pub fn van_rhijn(elevation_rad: f64, height_km: f64) -> f64 {
    let ratio = EARTH_RADIUS_KM / (EARTH_RADIUS_KM + height_km);
    let cos_e = elevation_rad.max(0.0).cos();
    1.0 / (1.0 - ratio * ratio * cos_e * cos_e).sqrt()
}

/// A unit direction's elevation above the horizon, radians.
pub fn elevation(d: Vec3) -> f64 {
    f64::from(d.y / d.length()).clamp(-1.0, 1.0).asin()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn julian_days_and_sidereal_time_match_meeus() {
        // Meeus example 7.a: 1957 October 4.81 = JD 2436116.31.
        let jd = julian_day("1957-10-04T19:26:24Z").unwrap();
        assert!((jd - 2_436_116.31).abs() < 1e-6, "{jd}");
        // Meeus example 12.b: 1987 April 10, 19:21:00 UT: GMST 8h34m57.0896s = 128.7378734°.
        let g = gmst_deg(julian_day("1987-04-10T19:21:00Z").unwrap());
        assert!((g - 128.737_873_4).abs() < 1e-5, "{g}");
        assert!(julian_day("2027-02-29T00:00:00Z").is_err());
        assert!(julian_day("2027-01-15 21:00").is_err());
    }

    #[test]
    fn polaris_stands_at_the_latitude_due_north_and_the_catalogue_is_whole() {
        let stars = catalogue();
        assert_eq!(stars.len(), 5044);
        assert!(stars.windows(2).all(|w| w[0].vmag <= w[1].vmag), "brightest first");
        let polaris = stars.iter().find(|s| s.hip == 11767).unwrap();
        for utc in ["2027-01-15T21:00:00Z", "2027-01-16T03:00:00Z"] {
            let d = direction(polaris, julian_day(utc).unwrap(), 69.65, 18.96);
            let elevation = d.y.asin().to_degrees();
            // Polaris is 0.66° from the pole in 2027: its elevation stays within that of
            // the latitude, and it stands within 2° of due north.
            assert!((elevation - 69.65).abs() < 0.7, "{utc}: {elevation}");
            assert!(d.x.atan2(d.z).to_degrees().abs() < 2.0, "{utc}: {d}");
        }
    }

    #[test]
    fn a_star_east_of_the_meridian_stands_on_the_east_side() {
        // Hour angle −2 h (rising, east of the meridian), declination +20°, seen from
        // 69.65° N: its east component −cos δ sin H is positive, so its world x is
        // negative (x points west).
        let jd = julian_day("2027-01-15T21:00:00Z").unwrap();
        let lst = gmst_deg(jd) + 18.96;
        let star = Star { hip: 0, ra_deg: lst + 30.0, dec_deg: 20.0, vmag: 0.0, bv: 0.6 };
        let d = direction(&star, jd, 69.65, 18.96);
        // (Precession to 2027 moves it by under half a degree.)
        let east = (20f64.to_radians().cos() * 30f64.to_radians().sin()).abs();
        assert!((d.x + east).abs() < 0.01, "{d}");
    }

    #[test]
    fn directions_turn_back_into_the_stars_coordinates_and_the_milky_way_is_where_it_is() {
        let jd = julian_day("2027-01-15T21:00:00Z").unwrap();
        for star in catalogue().iter().step_by(97) {
            let d = direction(star, jd, 69.65, 18.96);
            let (ra, dec) = equatorial(d, jd, 69.65, 18.96);
            // Precession moves a star by at most ~0.5° in 27 years (more near the poles).
            let (ra0, dec0) = (star.ra_deg, star.dec_deg);
            let dra = ((ra - ra0 + 180.0).rem_euclid(360.0) - 180.0) * dec0.to_radians().cos();
            assert!(dra.abs() < 0.6 && (dec - dec0).abs() < 0.3, "HIP {}: {ra}, {dec}", star.hip);
        }
        // The galactic centre (RA 266.4°, dec −28.9°) and Cygnus (RA 305°, dec +40°) lie
        // in it, the Large Sagittarius Star Cloud (RA 271°-274°, dec −27.5°) in its
        // brightest level; the galactic poles (RA 192.9°, dec +27.1°; RA 12.9°, dec
        // −27.1°), Orion's belt and Polaris do not.
        assert!(milky_way_level(266.4, -28.9) >= 1.0 && milky_way_level(305.0, 40.0) >= 1.0);
        assert_eq!(milky_way_level(273.0, -27.5), 5.0);
        assert_eq!(milky_way_level(83.8, -5.4), 0.0);
        for (ra, dec) in [(192.9, 27.1), (12.9, -27.1), (37.95, 89.26)] {
            assert_eq!(milky_way_level(ra, dec), 0.0, "({ra}, {dec})");
        }
    }

    #[test]
    fn the_sky_turns_once_a_sidereal_day() {
        let vega = catalogue().iter().find(|s| s.hip == 91262).unwrap();
        let jd = julian_day("2027-01-15T21:00:00Z").unwrap();
        let a = direction(vega, jd, 60.0, 10.0);
        let b = direction(vega, jd + 0.997_269_57, 60.0, 10.0);
        let c = direction(vega, jd + 0.25, 60.0, 10.0);
        assert!(a.angle_between(b).to_degrees() < 0.01, "{a} {b}");
        assert!(a.angle_between(c).to_degrees() > 10.0);
    }

    #[test]
    fn airglow_brightens_towards_the_horizon() {
        let glow = |e: f64| van_rhijn(e.to_radians(), 97.0) * glow_transmission(e.to_radians());
        assert!((van_rhijn(std::f64::consts::FRAC_PI_2, 97.0) - 1.0).abs() < 1e-12);
        // At 10°: van Rhijn 4.1 × (0.36 + 0.32) = 2.8 against the zenith's 0.92.
        assert!(glow(10.0) > 2.5 * glow(90.0), "{} {}", glow(10.0), glow(90.0));
        // At the horizon the path is longest (van Rhijn 5.7) and half the light is back.
        assert!(glow(0.0) > glow(10.0), "{} {}", glow(0.0), glow(10.0));
        // A star is dimmed by the whole extinction: 0.2 mag per airmass.
        assert!((transmission(std::f64::consts::FRAC_PI_2) - 10f64.powf(-0.08)).abs() < 1e-3);
    }
}
