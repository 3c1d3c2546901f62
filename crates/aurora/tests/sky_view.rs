//! The sky view end to end (its image evidence): colour by height in a rendered
//! curtain, the afterglow's decay, thread-count independence, and the dome and
//! panorama cameras.

use phenomena_aurora::deposition::{Precipitation, Spectrum};
use phenomena_aurora::emission::Line;
use phenomena_aurora::night::Airglow;
use phenomena_aurora::{AuroraConfig, AuroraSim, ColourMode, SkyCamera, SkyRenderer, SkySettings};
use phenomena_core::image::Frame;

/// The default arc with few particles, after a few frames.
fn sim(particles: u32, frames: u32) -> AuroraSim {
    let mut config = AuroraConfig::default();
    config.motion.particles = particles;
    config.redistribution.enabled = false;
    let mut sim = AuroraSim::new(config, 7).expect("default aurora");
    for _ in 0..frames {
        sim.step().expect("step");
    }
    sim
}

/// Sum of each channel over rows `rows` of `frame`.
fn rows_rgb(frame: &Frame, rows: std::ops::Range<usize>) -> [f64; 3] {
    let mut acc = [0.0; 3];
    for y in rows {
        for x in 0..frame.width() {
            let p = frame.pixel(x, y);
            acc[0] += f64::from(p.x);
            acc[1] += f64::from(p.y);
            acc[2] += f64::from(p.z);
        }
    }
    acc
}

#[test]
fn a_curtain_is_green_in_the_middle_and_redder_on_top() {
    // Seen from the side (an orbit camera level with the curtain, so that image rows map
    // to altitude), physical mode: rows are binned by altitude band through the camera.
    let settings = SkySettings {
        camera: SkyCamera::Orbit {
            altitude_km: 200.0,
            distance_km: 1500.0,
            look_at_altitude_km: 200.0,
            fov_y_deg: 16.0,
        },
        ..SkySettings::thesis()
    };
    let s = sim(20_000, 3);
    let mut sky = SkyRenderer::new(settings, 320, 240, None).expect("sky");
    let frame = sky.render(&s).clone();
    // Image rows of altitudes a..b at the curtain's distance (the centre of the plane is
    // 1500 km away; 240 px span 2·1500·tan 8° = 421.6 km, so 0.569 px/km).
    let px_per_km = 240.0 / (2.0 * 1500.0 * 8f64.to_radians().tan());
    let row = |alt: f64| (120.0 - (alt - 200.0) * px_per_km).round() as usize;
    let middle = rows_rgb(&frame, row(130.0)..row(100.0));
    let top = rows_rgb(&frame, row(300.0)..row(200.0));
    // Middle (100-130 km): green dominates (557.7 nm), as in real aurora.
    assert!(middle[1] > middle[0] && middle[1] > middle[2], "middle rows {middle:?}");
    // Top (200-300 km): the share of red is larger than in the middle (630.0 nm).
    let redness = |c: [f64; 3]| c[0] / (c[0] + c[1] + c[2]);
    assert!(redness(top) > 1.5 * redness(middle), "top {top:?} vs middle {middle:?}");
    assert!(top.iter().sum::<f64>() > 0.0);
    // And the bottom border sits near 100 km: little light below 90 km.
    let below = rows_rgb(&frame, row(90.0)..row(70.0)).iter().sum::<f64>();
    assert!(below < 0.05 * middle.iter().sum::<f64>(), "below 90 km: {below}");
}

#[test]
fn the_red_line_lingers_after_the_particles_move_on() {
    // Afterglow: render one curtain, then a second one elsewhere with the same renderer.
    // At the first curtain's place each line keeps exp(-Δt/τ) of its image: τ = 0 for the
    // prompt N2 lines (gone at once), ~0.8 s for 557.7 nm, tens of seconds for 630.0 nm.
    let first = sim(10_000, 2);
    let mut config = AuroraConfig::default();
    config.motion.particles = 10_000;
    for k in &mut config.keyframes {
        for sheet in &mut k.sheets {
            for p in sheet.iter_mut() {
                p[1] -= 150.0; // 150 km south: no overlap with the first curtain.
            }
        }
    }
    let mut second = AuroraSim::new(config, 7).expect("moved arc");
    second.step().expect("step");
    let settings = SkySettings { afterglow: true, ..SkySettings::thesis() };
    let mut sky = SkyRenderer::new(settings, 200, 120, None).expect("sky");
    sky.render(&first);
    let before = sky.line_images().clone();
    sky.render(&second);
    let after = sky.line_images();
    let column = sky.column_model().expect("physical");
    let dt = f64::from(first.config().motion.time_step_s);
    // Compare where the first curtain was bright and the second adds nothing: pixels
    // above 10 % of the first image's peak whose new 427.8 nm light is zero.
    let k428 = Line::N2p428.index();
    let peak = before[k428].data().iter().cloned().fold(0.0f32, f32::max);
    let mask: Vec<bool> = before[k428]
        .data()
        .iter()
        .zip(after[k428].data())
        .map(|(b, a)| *b > 0.1 * peak && *a == 0.0)
        .collect();
    assert!(mask.iter().filter(|&&m| m).count() > 50, "the curtains overlap too much to test");
    for line in [Line::O557, Line::O630] {
        let k = line.index();
        let (mut kept, mut had) = (0.0f64, 0.0f64);
        for ((b, a), m) in before[k].data().iter().zip(after[k].data()).zip(&mask) {
            if *m {
                kept += f64::from(*a);
                had += f64::from(*b);
            }
        }
        let expected = (-dt / column.effective_lifetime_s(line)).exp();
        // The second curtain's light reaches these pixels only through the blur's
        // far tail (σ ≤ 2.5 px, the curtains 150 km apart); f32 rounding 1e-6.
        assert!((kept / had - expected).abs() < 1e-3, "{line:?}: kept {} expected {expected}", kept / had);
    }
}

#[test]
fn sky_renders_are_identical_for_one_and_two_threads() {
    let s = sim(8_000, 2);
    for mode in [ColourMode::Physical, ColourMode::Paper] {
        let settings = SkySettings { mode, ..SkySettings::thesis() };
        let render = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let mut sky = SkyRenderer::new(settings.clone(), 160, 90, None).expect("sky");
                sky.render(&s).to_interleaved()
            })
        };
        let (one, two) = (render(1), render(2));
        assert!(one.iter().any(|&v| v > 0.0), "{mode:?}: empty image");
        assert!(one.iter().zip(&two).all(|(a, b)| a.to_bits() == b.to_bits()), "{mode:?}");
    }
}

#[test]
fn the_dome_master_shows_the_sky_inside_its_circle() {
    let s = sim(8_000, 2);
    let settings = SkySettings { camera: SkyCamera::Dome { fov_deg: 180.0 }, ..SkySettings::thesis() };
    let mut sky = SkyRenderer::new(settings, 128, 128, None).expect("sky");
    let frame = sky.render(&s);
    let (mut inside, mut outside) = (0.0f64, 0.0f64);
    for y in 0..128 {
        for x in 0..128 {
            let p = frame.pixel(x, y);
            let v = f64::from(p.x + p.y + p.z);
            let r = ((x as f64 + 0.5 - 64.0).powi(2) + (y as f64 + 0.5 - 64.0).powi(2)).sqrt();
            // Outside the circle plus the splat's reach (a few px) nothing is drawn.
            if r > 68.0 {
                outside += v.abs();
            } else {
                inside += v;
            }
        }
    }
    assert!(inside > 0.0 && outside == 0.0, "inside {inside}, outside {outside}");
}

#[test]
fn the_panorama_shows_the_arc_above_the_horizon_from_east_to_west() {
    // Equirectangular from the ground under the plane's centre, north at the centre
    // column, east at 3/4 of the width: the default arc runs from 140 km west to 140 km
    // east of the observer, 0-40 km south of it, 100-400 km up, so all its light is
    // above the horizon (upper half) and reaches both the eastern and western quarters.
    let s = sim(8_000, 2);
    let settings = SkySettings { camera: SkyCamera::Panorama, ..SkySettings::thesis() };
    let mut sky = SkyRenderer::new(settings, 360, 180, None).expect("sky");
    let frame = sky.render(&s);
    let upper = rows_rgb(frame, 0..90).iter().sum::<f64>();
    let lower = rows_rgb(frame, 90..180).iter().sum::<f64>();
    assert!(upper > 0.0 && lower < 1e-3 * upper, "upper {upper}, lower {lower}");
    let columns = |xs: std::ops::Range<usize>| {
        let mut v = 0.0f64;
        for y in 0..90 {
            for x in xs.clone() {
                let p = frame.pixel(x, y);
                v += f64::from(p.x + p.y + p.z);
            }
        }
        v
    };
    let (east, west) = (columns(225..315), columns(45..135));
    assert!(east > 0.1 * upper && west > 0.1 * upper, "east {east}, west {west} of {upper}");
}

#[test]
fn the_ground_hides_what_is_below_the_horizon_and_stars_shine_above_it() {
    // Panorama: rows below the horizon are below the hills' lowest point (-0.1°: the
    // hills are 1.5° ± 1.6°), so with the ground on they are black; stars add light only
    // above the hills.
    let s = sim(4_000, 1);
    let base = SkySettings { camera: SkyCamera::Panorama, ..SkySettings::thesis() };
    let render = |settings: SkySettings| {
        let mut sky = SkyRenderer::new(settings, 360, 180, None).expect("sky");
        sky.render(&s).clone()
    };
    let plain = render(base.clone());
    let starry = render(SkySettings { stars: true, ground: true, ..base });
    // Elevation of row y's centre: 90° - (y + 0.5)·1°. Rows 91.. are below -0.5°.
    let lower = rows_rgb(&starry, 91..180);
    assert_eq!(lower, [0.0; 3], "ground rows");
    let mut added = 0usize;
    for y in 0..85 {
        for x in 0..360 {
            let (a, b) = (plain.pixel(x, y), starry.pixel(x, y));
            if b.x > a.x + 1e-6 {
                added += 1;
            }
        }
    }
    // The catalogue holds 2,851 stars to magnitude 5.5, about half of them above the
    // horizon at any time, each over up to 4 pixels (bilinear): several hundred lit
    // pixels.
    assert!(added > 500, "{added} pixels gained starlight");
}

#[test]
fn airglow_brightens_towards_the_horizon_in_the_frame() {
    // Panorama, aurora far off to the north (its particles only cover azimuths near
    // 0°): columns 90-150 (azimuth 90-150°, east to south-east) hold only the glow.
    // With the emission lines alone (the continuum of starlight and zodiacal light,
    // which comes from no layer, turned down to nothing), each row's mean there rises
    // from the zenith towards the horizon, as the van Rhijn factor and extinction say
    // (2.8 times at 10° elevation, 1.7 at 30°), and the ground is black.
    let s = sim(4_000, 1);
    let lines_only = Airglow { continuum_mag_arcsec2: 40.0, ..Airglow::default() };
    let settings = SkySettings {
        camera: SkyCamera::Panorama,
        airglow: true,
        airglow_zenith: lines_only,
        ground: true,
        ..SkySettings::thesis()
    };
    let mut sky = SkyRenderer::new(settings, 360, 180, None).expect("sky");
    let frame = sky.render(&s).clone();
    let row = |y: usize| (90..150).map(|x| f64::from(frame.pixel(x, y).y)).sum::<f64>() / 60.0;
    // Row y's centre is at elevation 90° − (y + 0.5)°.
    let (zenith, at_30, at_10) = (row(0), row(59), row(79));
    assert!(zenith > 0.0, "the glow at the zenith");
    assert!(at_30 > 1.5 * zenith && at_10 > 2.3 * zenith, "{zenith} {at_30} {at_10}");
    assert_eq!(row(95), 0.0, "the ground");
}

#[test]
fn the_paper_mode_ignores_the_small_scale_motion() {
    // The thesis's mode draws the particles where the simulation puts them (§2.4):
    // switching the small-scale motion off changes none of its pixels.
    let s = sim(4_000, 2);
    let mut config = s.config().clone();
    config.small_scale.enabled = false;
    let mut still = AuroraSim::new(config, s.seed()).expect("sim");
    for _ in 0..2 {
        still.step().expect("step");
    }
    let settings = SkySettings { mode: ColourMode::Paper, ..SkySettings::thesis() };
    let render =
        |sim: &AuroraSim| SkyRenderer::new(settings.clone(), 160, 90, None).expect("sky").render(sim).clone();
    let (a, b) = (render(&s), render(&still));
    assert!(a == b, "paper frames differ");
    // ...while the physical mode draws it.
    let physical = SkySettings { mode: ColourMode::Physical, ..settings.clone() };
    let render =
        |sim: &AuroraSim| SkyRenderer::new(physical.clone(), 160, 90, None).expect("sky").render(sim).clone();
    let (a, b) = (render(&s), render(&still));
    assert!(a != b, "physical frames equal");
}

#[test]
fn the_phases_of_a_particle_subset_average_to_the_full_image() {
    // The preview's particle subset (every k-th particle, k times the weight) is
    // unbiased: the k phases partition the particles, so their mean is the full image,
    // up to f32 rounding of the sums (relative 1e-4 is ~800 ulps of headroom).
    let s = sim(20_000, 3);
    let settings = SkySettings { mode: ColourMode::Paper, ..SkySettings::thesis() };
    let mut full = SkyRenderer::new(settings.clone(), 160, 90, None).expect("sky");
    full.render(&s);
    let reference: Vec<Vec<f32>> = full.line_images().iter().map(|p| p.data().to_vec()).collect();
    let k = 4;
    let mut mean = vec![vec![0.0f64; reference[0].len()]; 5];
    let mut one_phase_differs = false;
    for phase in 0..k {
        let mut sky = SkyRenderer::new(settings.clone(), 160, 90, None).expect("sky");
        sky.set_particle_subset(k, phase);
        sky.render(&s);
        for (m, (plane, r)) in mean.iter_mut().zip(sky.line_images().iter().zip(&reference)) {
            for (acc, v) in m.iter_mut().zip(plane.data()) {
                *acc += f64::from(*v) / k as f64;
            }
            one_phase_differs |= plane.data() != r.as_slice();
        }
    }
    assert!(one_phase_differs, "a phase alone should differ from the full image");
    for (line, (m, r)) in mean.iter().zip(&reference).enumerate() {
        let total: f64 = r.iter().map(|v| f64::from(*v)).sum();
        let diff: f64 = m.iter().zip(r).map(|(a, b)| (a - f64::from(*b)).abs()).sum();
        assert!(diff <= 1e-4 * total.max(1e-30), "line {line}: |mean - full| = {diff} of {total}");
    }
}

#[test]
fn a_reused_renderer_leaves_no_trace_of_earlier_frames() {
    // The renderer keeps its point buffers, filing and line images between frames (issue
    // 23). Without afterglow a frame must not depend on what was rendered before it: a
    // renderer that drew a denser, different sim first gives the same bits as a fresh one.
    for mode in [ColourMode::Physical, ColourMode::Paper] {
        let settings = SkySettings { mode, afterglow: false, ..SkySettings::thesis() };
        let (before, now) = (sim(12_000, 4), sim(5_000, 2));
        let mut reused = SkyRenderer::new(settings.clone(), 160, 90, None).expect("sky");
        // Two frames: the renderer alternates two sets of line images.
        reused.render(&before);
        reused.render(&before);
        let again = reused.render(&now).clone();
        let fresh = SkyRenderer::new(settings, 160, 90, None).expect("sky").render(&now).clone();
        assert!(rows_rgb(&fresh, 0..90).iter().sum::<f64>() > 0.0, "{mode:?}: a lit frame");
        assert_eq!(again, fresh, "{mode:?}");
    }
}

/// Widths of `precipitation`'s curtain seen level from the side, 1500 km away with a 4°
/// field (2.29 px per km of altitude at the curtain): luminance per row summed over the
/// width; (peak altitude, lower border 10 → 90 % of the peak, top 90 → 10 %), km.
fn border_widths(precipitation: Precipitation) -> (f64, f64, f64) {
    let settings = SkySettings {
        camera: SkyCamera::Orbit {
            altitude_km: 140.0,
            distance_km: 1500.0,
            look_at_altitude_km: 140.0,
            fov_y_deg: 4.0,
        },
        precipitation,
        ..SkySettings::thesis()
    };
    let s = sim(20_000, 3);
    let mut sky = SkyRenderer::new(settings, 320, 240, None).expect("sky");
    let frame = sky.render(&s).clone();
    let px_per_km = 240.0 / (2.0 * 1500.0 * 2f64.to_radians().tan());
    let rows: Vec<f64> =
        (0..240).map(|y| (0..320).map(|x| f64::from(frame.pixel(x, y).y)).sum::<f64>()).collect();
    let (peak_row, peak) =
        rows.iter().enumerate().fold((0, 0.0), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
    // The last row (moving away from the peak) at or above `share` of it.
    let reach = |share: f64, step: i64| {
        let mut y = peak_row as i64;
        while (0..240).contains(&(y + step)) && rows[(y + step) as usize] >= share * peak {
            y += step;
        }
        assert!((1..239).contains(&y), "the curtain runs out of the frame");
        y
    };
    let km = |a: i64, b: i64| (a - b).abs() as f64 / px_per_km;
    let peak_km = 140.0 + (120.0 - peak_row as f64 - 0.5) / px_per_km;
    (peak_km, km(reach(0.1, 1), reach(0.9, 1)), km(reach(0.1, -1), reach(0.9, -1)))
}

#[test]
#[allow(clippy::print_stderr)] // the measures, for the notes (--nocapture)
fn the_lower_border_is_sharp_and_the_top_fades() {
    // Observed: a curtain's lower border goes from dark to bright in a few km, its top
    // fades over tens of km. The default Maxwellian (2 keV, whose fast tail reaches
    // deeper) and a mono-energetic 5 keV beam (an inverted-V arc's accelerated
    // electrons): the lower border within 10 and 5 km, the top over at least 20 km and
    // at least three times the lower border's width.
    let maxwellian = border_widths(Precipitation::default());
    let mono = border_widths(Precipitation {
        spectrum: Spectrum::Mono,
        energy_kev: 5.0,
        ..Precipitation::default()
    });
    for ((peak, lower, upper), name, limit) in
        [(maxwellian, "maxwellian 2 keV", 10.0), (mono, "mono 5 keV", 5.0)]
    {
        eprintln!(
            "{name}: peak at {peak:.0} km; lower border 10-90 % over {lower:.1} km; top 90-10 % over {upper:.1} km"
        );
        assert!(lower <= limit, "{name}: lower border over {lower} km");
        assert!(upper >= 20.0 && upper >= 3.0 * lower, "{name}: top fades over {upper} km");
    }
}
