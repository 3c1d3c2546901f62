//! `phenomena new`: commented starter scenes holding every default.

/// A flame scene with every parameter at its default, each explained.
pub(crate) const FLAME: &str = r#"# A phenomena flame scene. Render it with
#   phenomena render flame.toml --out out/flame
# Every value below is the default; delete what you do not change.
# Units are in the names: _m metres, _s seconds, _k kelvin, _kg kilograms.

[scene]
frames = 120            # frames to render (60 per second of simulated time by default)
width = 1280            # pixels
height = 720
seed = 1                # every random number derives from this
exposure_ev = 0.0       # PNG only: exposure compensation in stops
tone_map = "aces"       # PNG only: "aces", "reinhard" or "clamp"

[flame]
mode = "extended"       # "paper": Inagaki et al. as printed (constant temperature);
                        # "extended": cooling, buoyancy, no negative pressure
frame_time_s = 0.016666668   # one frame of 60 fps
substeps = 1            # SPH steps per frame (the paper: 1)
max_particles = 200000  # emission pauses at this count

[flame.sph]             # paper §4.2
support_radius_m = 0.04       # d of the poly6 kernel, eq (2)
particle_mass_kg = 1e-5       # m, the same for every particle
rest_density_kg_m3 = 1.0      # ρ0 of eq (11)
gas_constant_m2_s2 = 0.1      # k of eq (11): p = k(ρ - ρ0)
pressure_kernel = "spiky"     # gradient in eq (12): "spiky" or "poly6" (as printed)

[flame.emitter]         # the burner, paper §4.3 step 1
position_m = [0.0, 0.0, 0.0]  # centre of a horizontal disk
radius_m = 0.08
rate_per_s = 3000.0           # particles per second
velocity_m_s = [0.0, 0.8, 0.0]
velocity_jitter_m_s = 0.05    # standard deviation per axis
temperature_k = 1900.0
lifetime_s = 1.0              # particles are removed at the end of their life
lifetime_jitter = 0.3         # lifetimes spread over ±30 %

[flame.wind]            # the external force, paper §4.2.3
force_n_m3 = [0.0, 0.0, 0.0]  # constant force per unit volume; or keyframes:
# [[flame.wind.keys]]
# time_s = 0.0
# force_n_m3 = [0.5, 0.0, 0.0]

[flame.extended]        # used only in "extended" mode
ambient_temperature_k = 300.0
cooling_time_s = 1.5          # T = T_amb + (T_0 - T_amb) exp(-age / cooling_time_s)
temperature_jitter_k = 80.0   # spread of the birth temperature
buoyancy_m_s2_per_k = 0.001   # upward acceleration per kelvin above ambient
clamp_negative_pressure = true

[flame.domain]          # particles leaving this box are removed
min_m = [-2.0, -0.5, -2.0]
max_m = [2.0, 3.0, 2.0]

[render]                # paper §5
intensity = 0.35              # radiance at the centre of one opaque particle
splat_radius_scale = 1.0      # splat radius in units of the support radius
brightness = "radiometric"    # "normalized": colour only (Fig 1); "radiometric": Planck
reference_temperature_k = 1900.0  # radiometric: brightness 1 at this temperature
full_alpha_density_ratio = 1.0    # opaque at this multiple of the rest density
resolution_scale = 0.5        # splat buffers at this fraction of the frame (1 = paper)
view = "flame"                # "flame", or "density" (particles as squares, Fig 7)

[render.camera]                # if given, position, look_at and projection are required
position = [0.0, 0.45, 2.2]
look_at = [0.0, 0.45, 0.0]
up = [0.0, 1.0, 0.0]
projection = { kind = "perspective", fov_y_deg = 35.0 }
# projection = { kind = "orthographic", height_m = 1.5 }

[render.shimmer]        # heat haze, paper §5.3
enabled = true
strength_m = 0.002            # largest background shift per particle, metres at the flame
radius_scale = 1.0            # refraction footprint relative to the splat

[render.background]
kind = "checker"
squares_per_height = 12.0
light = [0.08, 0.08, 0.08]    # linear RGB
dark = [0.02, 0.02, 0.02]
# or, instead of the three lines above:
# kind = "sky"
# zenith = [0.004, 0.006, 0.02]
# horizon = [0.07, 0.035, 0.03]
# or: kind = "image" with path = "background.png" (relative to this file), or kind = "black"
"#;

/// A sparkle scene with every parameter at its default, each explained.
pub(crate) const SPARKLE: &str = r#"# A phenomena sparkle scene (Hwang and Noma: only the facets that can be seen are
# created). Render it with
#   phenomena render sparkle.toml --out out/sparkle --stats out/sparkle.jsonl
# Every value below is the default; delete what you do not change.

[scene]
frames = 120            # frames to render
width = 1280            # pixels
height = 720
seed = 1                # every random number derives from this
exposure_ev = 0.0       # PNG only: exposure compensation in stops
tone_map = "aces"       # PNG only: "aces", "reinhard" or "clamp"

[sparkle]
method = "stochastic"   # the paper's model; "brute-force" simulates every facet (Table 1)
fps = 30.0              # the time step is 1/fps
memory_frames = 4       # frames a faded glint is still followed (0 = the paper's plain delete)

[sparkle.phong]         # §2: seen when k_s I_l (N·H)^n >= I_e
specular_k_s = 1.0
light_intensity = 1.0   # I_l
threshold_i_e = 0.0025  # I_e; with n = 10,000 the cone is θ = 1.98°, 3.0e-4 of all facets
exponent_n = 10000.0    # n
two_sided = false       # the paper counts one face; plates and leaves reflect from both

[sparkle.light]         # or: kind = "point", position_m = [x, y, z] (a street lamp)
kind = "sun"
azimuth_deg = 20.0      # 0 = towards -z, 90 = towards +x
elevation_deg = 12.0
azimuth_rate_deg_per_s = 0.0
elevation_rate_deg_per_s = 0.0

[sparkle.camera]
position = [0.0, 1.6, 0.0]
look_at = [0.0, 4.0, -20.0]
up = [0.0, 1.0, 0.0]
projection = { kind = "perspective", fov_y_deg = 60.0 }

[sparkle.population]    # §3.1 diamond dust; or kind = "leaf-glitter" (§3.2) with
                        # centre_m, radius_m, count and spread_deg
kind = "diamond-dust"
box_min_m = [-50.0, 0.0, -100.0]   # a periodic box of air
box_max_m = [50.0, 20.0, 0.0]
density_per_m3 = 5000.0            # crystals per m³ (real diamond dust: 1e3-1e4): 1e9 here
fall_speed_m_per_s = 0.3
wind_m_per_s = [0.5, 0.0, 0.0]
gust_m_per_s = 0.3                 # a smooth gust shared by all crystals
turbulence_m_per_s = 0.1           # each crystal's own random step
rotation_deg_per_frame = 0.5       # largest random turn per frame
normals = { kind = "uniform" }     # or { kind = "plates", tilt_deg = 2.0 }: sun pillars

[render]
background = { kind = "sky" }      # or { kind = "black" }, { kind = "image", path = "bg.png" }
glint_gain = 4.0                   # radiance per unit of glint brightness
light_rgb = [1.0, 0.97, 0.92]
glare = "cross"                    # "none", "cross" or "star"
glare_length_px = 9.0
glare_strength = 0.35
glare_threshold = 0.5              # glints dimmer than this share of k_s I_l get no glare
sky_zenith_rgb = [0.06, 0.12, 0.3]
sky_horizon_rgb = [0.45, 0.55, 0.7]
ground_rgb = [0.55, 0.58, 0.62]
crown_rgb = [0.05, 0.16, 0.04]
falloff_from_m = 0.0               # > 0: glints beyond this distance dim as 1/r² (0 = the paper)
"#;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{FlameScene, Scene, SparkleScene, parse};
    use std::path::Path;

    #[test]
    fn the_starter_holds_exactly_the_defaults() {
        match parse(FLAME, Path::new("flame.toml")) {
            Ok(Scene::Flame(s)) => assert_eq!(*s, FlameScene::default()),
            Ok(other) => panic!("the flame starter parsed as a {} scene", other.phenomenon()),
            Err(e) => panic!("{e}"),
        }
        match parse(SPARKLE, Path::new("sparkle.toml")) {
            Ok(Scene::Sparkle(s)) => assert_eq!(*s, SparkleScene::default()),
            Ok(other) => panic!("the sparkle starter parsed as a {} scene", other.phenomenon()),
            Err(e) => panic!("{e}"),
        }
    }
}
