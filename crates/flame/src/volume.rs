//! The flame as volumes: the SPH fields of §4 sampled at the centres of a
//! voxel grid, for OpenVDB files a renderer such as Blender's Cycles reads.
//!
//! At a voxel centre x, with the poly6 density kernel W of §4.2 (support d) and each
//! particle's volume V_j = m_j / ρ_j:
//! - `density` ρ(x) = Σ m_j W(x − x_j) (eq 3), kg/m³;
//! - `temperature` T(x) = Σ V_j T_j W / Σ V_j W (the SPH interpolation normalised by
//!   Shepard's Σ V_j W, so a lone particle keeps its own temperature), kelvin;
//! - `emission` E(x) = Σ V_j W(x − x_j) c_j with c_j the colour the renderer gives the
//!   particle (§5: the blackbody table at T_j times `intensity` times the alpha from
//!   density): linear sRGB, the renderer's particle colour per unit of SPH volume
//!   fraction (≈ c inside the gas). A volume shader's emission strength scales it.
//!
//! World space is the simulation's (metres, y up): voxel (i, j, k) is centred at
//! (i, j, k) × voxel size. Each 8³ leaf of the grid is summed on its own (in parallel),
//! from the particles that reach it in particle order, eight voxels of a row along z at
//! a time, so the sums do not depend on the thread count. Voxels where the particles'
//! volume fraction Σ V_j W is below [`MIN_FRACTION`] are left empty.

use phenomena_core::kernel::{Dim, Kernel, KernelKind};
use phenomena_core::vdb::{Grid, GridClass, Transform, VdbError};
use rayon::prelude::*;
use wide::f32x8;

use crate::air::Air;
use crate::config::FlameConfig;
use crate::render::{BlackbodyLut, RenderSettings};
use crate::sim::Particles;

/// Most voxels the leaves of one frame may span (each leaf's sums take 12 KiB while
/// they are made: 2^26 voxels is 1.5 GiB).
pub const MAX_VOXELS: u64 = 1 << 26;

/// The three grids of one frame.
#[derive(Clone, Debug)]
pub struct FlameVolume {
    /// Density, kg/m³.
    pub density: Grid<f32>,
    /// Temperature, K.
    pub temperature: Grid<f32>,
    /// Emission, linear sRGB.
    pub emission: Grid<[f32; 3]>,
}

/// Why a volume cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VolumeError {
    /// The voxel size is not usable.
    #[error("voxel size {0} m: expected a finite size in (0, 10] m")]
    VoxelSize(f64),
    /// The flame's box would need too many voxels at this size.
    #[error("the flame spans {voxels} voxels of {voxel_m} m (at most {MAX_VOXELS}): use larger voxels")]
    TooLarge {
        /// Voxels needed.
        voxels: u64,
        /// The voxel size, m.
        voxel_m: f64,
    },
    /// A particle lies too far from the origin for this voxel size.
    #[error(
        "a particle at {position_m:?} m is more than 2^23 voxels of {voxel_m} m from the origin: use larger voxels"
    )]
    Extent {
        /// Where.
        position_m: [f32; 3],
        /// The voxel size, m.
        voxel_m: f64,
    },
    /// The air around the flame reaches too far from the origin for its cell size (the
    /// wind has carried its axis away).
    #[error(
        "the air around the flame reaches {position_m:?} m, more than 2^23 of its {voxel_m} m cells from the origin"
    )]
    AirExtent {
        /// Where.
        position_m: [f32; 3],
        /// The air's cell size, m.
        voxel_m: f64,
    },
    /// The grid refused a value.
    #[error(transparent)]
    Grid(#[from] VdbError),
}

/// Bytes a frame's volume of `particles` particles (at most) takes at `voxel_m`: the
/// (leaf, particle) list and the three grids with their encoded copy, the leaves
/// bounded by what the particles can reach and by the domain; refused like
/// [`voxelize`] (a bad size, more than [`MAX_VOXELS`]) without making anything. An
/// upper bound: particles that share leaves need fewer.
pub fn volume_bytes(particles: usize, config: &FlameConfig, voxel_m: f64) -> Result<u64, VolumeError> {
    if !(voxel_m.is_finite() && voxel_m > 0.0 && voxel_m <= 10.0) {
        return Err(VolumeError::VoxelSize(voxel_m));
    }
    let per_particle = leaves_per_particle(config, voxel_m)?;
    let n = particles as u64;
    let size = (config.domain.max_m - config.domain.min_m).as_dvec3() / (8.0 * voxel_m);
    let domain = (size.x.ceil() + 2.0) * (size.y.ceil() + 2.0) * (size.z.ceil() + 2.0);
    let leaves = (n.saturating_mul(per_particle) as f64).min(domain).min((MAX_VOXELS / 512) as f64) as u64;
    // A (leaf, particle) entry is 16 bytes; a leaf holds 512 voxels of 1 + 1 + 3 floats
    // in the grids and about as much again encoded.
    Ok(n.saturating_mul(per_particle).saturating_mul(16).saturating_add(leaves * 512 * 20 * 2))
}

/// Most leaves one particle's support reaches at `voxel_m` (a cube of leaves), refused
/// when one particle alone would span more than [`MAX_VOXELS`].
fn leaves_per_particle(config: &FlameConfig, voxel_m: f64) -> Result<u64, VolumeError> {
    let reach = (f64::from(config.sph.support_radius_m) / voxel_m).ceil();
    // Voxels c - reach ..= c + reach fall in at most this many leaves of 8 per axis.
    let side = (2.0 * reach / 8.0).floor() + 2.0;
    let leaves = side * side * side;
    if leaves * 512.0 > MAX_VOXELS as f64 {
        return Err(VolumeError::TooLarge { voxels: (leaves * 512.0).min(u64::MAX as f64) as u64, voxel_m });
    }
    Ok(leaves as u64)
}

/// The air around the flame ([`crate::air`]) as a `velocity` grid: vec3, m/s, world
/// space (y up), the wind's drift included, for a renderer to motion-blur the volume by
/// (Blender's Cycles and Houdini look for a grid of this name) or a smoke solver to
/// advect by. One voxel per air cell: voxel (i, j, k) is centred at (i, j, k) times the
/// air's cell size, and every voxel whose centre lies inside the air's cylinder
/// ([`Air::contains`]) holds the air's velocity there ([`Air::velocity_at`]). Outside
/// the cylinder the air is not solved, and inside its obstacles there is none: the
/// grid is empty there.
pub fn air_velocity(air: &Air) -> Result<Grid<[f32; 3]>, VolumeError> {
    let (nr, nz, dx) = air.grid().shape();
    let voxel_m = f64::from(dx);
    let mut grid = Grid::new("velocity", Transform::new(voxel_m, [0.0; 3])?, GridClass::Unknown);
    grid.insert_metadata("units", "m/s")?;
    let (radius, ground) = (nr as f32 * dx, air.ground_m());
    let limit = (MAX_INDEX - 8) as f32;
    let (y_lo, y_hi) = ((ground / dx).floor(), ((ground + nz as f32 * dx) / dx).ceil());
    // Row by row, over the square around that row's (displaced) axis.
    for y in y_lo as i64..=y_hi as i64 {
        let axis = air.axis_at(y as f32 * dx - ground);
        let (lo, hi) = (((axis - radius) / dx).floor(), ((axis + radius) / dx).ceil());
        let corners = [lo.x, lo.y, hi.x, hi.y, y as f32];
        if corners.iter().any(|c| !(c.abs() <= limit)) {
            let position_m = [axis.x, y as f32 * dx, axis.y];
            return Err(VolumeError::AirExtent { position_m, voxel_m });
        }
        let y = y as i32;
        for x in lo.x as i32..=hi.x as i32 {
            for z in lo.y as i32..=hi.y as i32 {
                let p = glam::Vec3::new(x as f32, y as f32, z as f32) * dx;
                if air.contains(p) && !air.in_obstacle(p) {
                    grid.set([x, y, z], air.velocity_at(p).to_array());
                }
            }
        }
    }
    Ok(grid)
}

/// Bytes [`air_velocity`] takes for `air` at most, however the wind has displaced its
/// rows: the grid and its encoded copy (12 bytes a voxel each) over the 8³ leaves each
/// row of voxels can touch, the leaves of a square of the cylinder's diameter.
pub fn air_velocity_bytes(air: &Air) -> u64 {
    let (nr, nz, _) = air.grid().shape();
    // A row's square spans 2 nr + 3 voxels: at most ⌈(2 nr + 3)/8⌉ + 1 leaves a side.
    let side = ((2 * nr + 3).div_ceil(8) + 1) as u64;
    (nz as u64 + 2) * side * side * 512 * 24
}

/// Leaf coordinates fit in 21 bits each (voxel indices within ±2^23).
const MAX_INDEX: i64 = 1 << 23;

/// Voxels whose SPH volume fraction Σ V_j W is below this are left empty (the last
/// sliver of the kernels' tails).
pub const MIN_FRACTION: f32 = 1e-6;

/// One 8³ leaf's sums, z fastest in lanes (OpenVDB's order: offset x·64 + y·8 + z).
struct Brick {
    density: [f32x8; 64],
    vt: [f32x8; 64],
    v: [f32x8; 64],
    rgb: [[f32x8; 64]; 3],
}

/// Sample the particles' fields at `voxel_m` voxels (see the module docs); particles that
/// are not finite are left out. An animation should keep a [`Voxelizer`] instead, which
/// reuses its memory from frame to frame.
pub fn voxelize(
    particles: &Particles,
    config: &FlameConfig,
    settings: &RenderSettings,
    lut: &BlackbodyLut,
    voxel_m: f64,
) -> Result<FlameVolume, VolumeError> {
    let mut v = Voxelizer::default();
    v.voxelize(particles, config, settings, lut, voxel_m)?;
    v.volume.ok_or(VolumeError::VoxelSize(voxel_m))
}

/// Makes a frame's [`FlameVolume`], keeping the grids' and its own buffers for the next
/// frame (a frame's grids are tens of megabytes; allocating them afresh costs a page
/// fault per 4 KiB).
#[derive(Debug, Default)]
pub struct Voxelizer {
    volume: Option<FlameVolume>,
    pairs: Vec<(u64, u32)>,
}

impl Voxelizer {
    /// This frame's volume of `particles` ([`voxelize`]).
    pub fn voxelize(
        &mut self,
        particles: &Particles,
        config: &FlameConfig,
        settings: &RenderSettings,
        lut: &BlackbodyLut,
        voxel_m: f64,
    ) -> Result<&FlameVolume, VolumeError> {
        if !(voxel_m.is_finite() && voxel_m > 0.0 && voxel_m <= 10.0) {
            return Err(VolumeError::VoxelSize(voxel_m));
        }
        let reuse = self.volume.as_ref().is_some_and(|v| v.density.transform().voxel_size_m() == voxel_m);
        if reuse {
            if let Some(v) = self.volume.as_mut() {
                v.density.clear();
                v.temperature.clear();
                v.emission.clear();
            }
        } else {
            self.volume = Some(FlameVolume::empty(voxel_m)?);
        }
        let Some(volume) = self.volume.as_mut() else { return Err(VolumeError::VoxelSize(voxel_m)) };
        fill(volume, &mut self.pairs, particles, config, settings, lut, voxel_m)?;
        Ok(volume)
    }
}

impl FlameVolume {
    /// Three empty grids of `voxel_m` voxels, named and with their units.
    fn empty(voxel_m: f64) -> Result<Self, VolumeError> {
        let transform = Transform::new(voxel_m, [0.0; 3])?;
        let mut volume = FlameVolume {
            density: Grid::new("density", transform, GridClass::FogVolume),
            temperature: Grid::new("temperature", transform, GridClass::Unknown),
            emission: Grid::new("emission", transform, GridClass::Unknown),
        };
        volume.density.insert_metadata("units", "kg/m^3")?;
        volume.temperature.insert_metadata("units", "K")?;
        volume.emission.insert_metadata("units", "linear sRGB")?;
        Ok(volume)
    }
}

/// Fill empty grids with the particles' fields.
fn fill(
    volume: &mut FlameVolume,
    pairs: &mut Vec<(u64, u32)>,
    particles: &Particles,
    config: &FlameConfig,
    settings: &RenderSettings,
    lut: &BlackbodyLut,
    voxel_m: f64,
) -> Result<(), VolumeError> {
    let support = config.sph.support_radius_m;
    let h = voxel_m as f32;
    let reach = i64::from((support / h).ceil() as i32);
    // Refused before the list is made when it would be too long: one particle's leaves
    // over the cap, or the list longer than the cap (16 bytes an entry).
    let per_particle = leaves_per_particle(config, voxel_m)?;
    let entries = (particles.position_m.len() as u64).saturating_mul(per_particle);
    if entries > MAX_VOXELS {
        return Err(VolumeError::TooLarge { voxels: entries.saturating_mul(512), voxel_m });
    }
    list_leaf_pairs(pairs, particles, voxel_m, reach)?;
    let groups: Vec<&[(u64, u32)]> = pairs.chunk_by(|a, b| a.0 == b.0).collect();
    let voxels = groups.len() as u64 * 512;
    if voxels > MAX_VOXELS {
        return Err(VolumeError::TooLarge { voxels, voxel_m });
    }
    let lane = f32x8::from([0.0f32, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    let sums = LeafSums {
        particles,
        kernel: Kernel::new(KernelKind::Poly6, Dim::Three, support),
        voxel_m: h,
        reach,
        support_sq: support * support,
        full_alpha: config.sph.rest_density_kg_m3 * settings.full_alpha_density_ratio,
        intensity: settings.intensity,
        lut,
    };
    // One leaf per group in each grid, in group order, then filled in place.
    let origins: Vec<[i32; 3]> = groups.iter().map(|g| leaf_origin(g[0].0)).collect();
    let clash = || VolumeError::TooLarge { voxels, voxel_m };
    let density = volume.density.append_leaves(&origins).ok_or_else(clash)?;
    let temperature = volume.temperature.append_leaves(&origins).ok_or_else(clash)?;
    let emission = volume.emission.append_leaves(&origins).ok_or_else(clash)?;
    groups
        .par_iter()
        .zip(density.par_iter_mut())
        .zip(temperature.par_iter_mut().zip(emission.par_iter_mut()))
        .for_each(|((group, density), (temperature, emission))| {
            let origin = leaf_origin(group[0].0);
            let mut b = Brick {
                density: [f32x8::ZERO; 64],
                vt: [f32x8::ZERO; 64],
                v: [f32x8::ZERO; 64],
                rgb: [[f32x8::ZERO; 64]; 3],
            };
            let z = (f32x8::splat(origin[2] as f32) + lane) * f32x8::splat(h);
            for &(_, i) in group.iter() {
                sums.add_particle(&mut b, origin, z, i as usize);
            }
            finish_leaf(&b, density, temperature, emission);
        });
    Ok(())
}

/// Every (leaf, particle) pair where a finite particle reaches (`reach` voxels of
/// `voxel_m`) into the leaf, into `pairs`, sorted by leaf and then particle: each leaf
/// sums its particles in particle order. A particle too far out for the grid's indices
/// is refused.
fn list_leaf_pairs(
    pairs: &mut Vec<(u64, u32)>,
    particles: &Particles,
    voxel_m: f64,
    reach: i64,
) -> Result<(), VolumeError> {
    let h = voxel_m as f32;
    pairs.clear();
    for (i, x) in particles.position_m.iter().enumerate() {
        if !x.is_finite() {
            continue;
        }
        let c = x.to_array().map(|v| (v / h).round() as i64);
        if c.iter().any(|v| v.abs() > MAX_INDEX - reach - 8) {
            return Err(VolumeError::Extent { position_m: x.to_array(), voxel_m });
        }
        let range = |a: usize| ((c[a] - reach) >> 3)..=((c[a] + reach) >> 3);
        for lx in range(0) {
            for ly in range(1) {
                for lz in range(2) {
                    pairs.push((leaf_key([lx, ly, lz]), i as u32));
                }
            }
        }
    }
    pairs.par_sort_unstable();
    Ok(())
}

/// What a leaf's sums are made of (see the module docs): the particles, the poly6 kernel
/// W of support d, and the renderer's particle colour.
struct LeafSums<'a> {
    particles: &'a Particles,
    kernel: Kernel,
    /// Voxel size, m.
    voxel_m: f32,
    /// Voxels from a particle's voxel to the edge of its support.
    reach: i64,
    /// d², m².
    support_sq: f32,
    /// Density of full alpha, kg/m³.
    full_alpha: f32,
    intensity: f32,
    lut: &'a BlackbodyLut,
}

impl LeafSums<'_> {
    /// Add particle `i` to the sums `b` of the leaf at `origin` (voxels), whose voxel
    /// centres along z are `z` (m): m_j W, V_j T_j W, V_j W and V_j c_j W at every voxel of
    /// its support, eight voxels of a row along z at a time.
    #[inline]
    fn add_particle(&self, b: &mut Brick, origin: [i32; 3], z: f32x8, i: usize) {
        let (particles, h, reach) = (self.particles, self.voxel_m, self.reach);
        let p = particles.position_m[i];
        let rho = particles.density_kg_m3[i];
        let m = particles.mass_kg[i];
        let vol = if rho > 0.0 { m / rho } else { 0.0 };
        let t = particles.temperature_k[i];
        let alpha = (rho / self.full_alpha).clamp(0.0, 1.0);
        let c = self.lut.lookup(t) * (self.intensity * alpha);
        let dz = z - f32x8::splat(p.z);
        let dz2 = dz * dz;
        let span = |a: usize, v: f32| {
            let centre = (v / h).round() as i64;
            let lo = (centre - reach).max(i64::from(origin[a])) - i64::from(origin[a]);
            let hi = (centre + reach).min(i64::from(origin[a]) + 7) - i64::from(origin[a]);
            lo as usize..=hi.max(lo - 1) as usize
        };
        let (vm, vt, vv) = (f32x8::splat(m), f32x8::splat(vol * t), f32x8::splat(vol));
        let vc = [f32x8::splat(vol * c.x), f32x8::splat(vol * c.y), f32x8::splat(vol * c.z)];
        for x in span(0, p.x) {
            let dx = (origin[0] + x as i32) as f32 * h - p.x;
            for y in span(1, p.y) {
                let dy = (origin[1] + y as i32) as f32 * h - p.y;
                let dxy2 = dx * dx + dy * dy;
                // Rows outside the support's circle get nothing (W = 0 there).
                if dxy2 >= self.support_sq {
                    continue;
                }
                let w = self.kernel.value_sq_x8(dz2 + f32x8::splat(dxy2));
                let row = x * 8 + y;
                b.density[row] += vm * w;
                b.vt[row] += vt * w;
                b.v[row] += vv * w;
                for (k, ck) in vc.iter().enumerate() {
                    b.rgb[k][row] += *ck * w;
                }
            }
        }
    }
}

/// A leaf's sums as grid values; voxels under [`MIN_FRACTION`] stay empty (a leaf left
/// all empty is not written to the file).
fn finish_leaf(
    b: &Brick,
    density: &mut [f32; 512],
    temperature: &mut [f32; 512],
    emission: &mut [[f32; 3]; 512],
) {
    for row in 0..64 {
        let (rho, vt, v) = (b.density[row].to_array(), b.vt[row].to_array(), b.v[row].to_array());
        let rgb = b.rgb.map(|c| c[row].to_array());
        for z in 0..8 {
            if v[z] >= MIN_FRACTION && rho[z] > 0.0 {
                let k = row * 8 + z;
                density[k] = rho[z];
                temperature[k] = vt[z] / v[z];
                emission[k] = [rgb[0][z], rgb[1][z], rgb[2][z]];
            }
        }
    }
}

/// A leaf's coordinates (voxel index / 8, each within ±2^20) as one sortable key.
fn leaf_key(l: [i64; 3]) -> u64 {
    let bias = 1i64 << 20;
    l.iter().fold(0u64, |k, &v| (k << 21) | (v + bias) as u64)
}

/// The origin voxel of the leaf with key `k`.
fn leaf_origin(k: u64) -> [i32; 3] {
    let bias = 1i64 << 20;
    let mask = (1u64 << 21) - 1;
    [(k >> 42) & mask, (k >> 21) & mask, k & mask].map(|v| ((v as i64 - bias) * 8) as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::FlameSim;
    use glam::Vec3;

    fn sim_with(positions: Vec<Vec3>) -> FlameSim {
        let n = positions.len();
        FlameSim::with_particles(FlameConfig::default(), 1, positions, vec![Vec3::ZERO; n]).unwrap()
    }

    /// One particle: the density at its own voxel is m W(0), the temperature its own
    /// everywhere it reaches, and the grid's integral of density is its mass (the
    /// kernel is normalised; at 1 cm voxels and d = 4 cm the midpoint sum of poly6 is
    /// within 1 % of the integral).
    #[test]
    fn a_lone_particle_keeps_its_mass_and_temperature() {
        let sim = sim_with(vec![Vec3::new(0.013, 0.3, -0.021)]);
        let mut p = sim.particles().clone();
        p.density_kg_m3[0] = 0.8;
        let config = FlameConfig::default();
        let settings = RenderSettings::default();
        let lut = BlackbodyLut::new(settings.brightness, settings.reference_temperature_k);
        let v = voxelize(&p, &config, &settings, &lut, 0.01).unwrap();
        let ijk = [
            (p.position_m[0].x / 0.01).round() as i32,
            (p.position_m[0].y / 0.01).round() as i32,
            (p.position_m[0].z / 0.01).round() as i32,
        ];
        assert!(v.density.get(ijk) > 0.0);
        let mass: f64 =
            v.density.leaves().flat_map(|(_, l)| l.iter()).map(|&d| f64::from(d)).sum::<f64>() * 1e-6;
        let m = f64::from(p.mass_kg[0]);
        assert!((mass - m).abs() < 0.01 * m, "mass {mass} vs {m}");
        for (_, leaf) in v.temperature.leaves() {
            for &t in leaf.iter().filter(|&&t| t != 0.0) {
                assert!((t - p.temperature_k[0]).abs() < 1e-2 * p.temperature_k[0], "{t}");
            }
        }
        assert_eq!(v.density.active_voxel_count(), v.temperature.active_voxel_count());
    }

    #[test]
    fn bad_sizes_are_refused() {
        // Sparse leaves: particles far apart cost nothing between them, but an index
        // past ±2^23 voxels is refused.
        let sim = sim_with(vec![Vec3::ZERO, Vec3::new(1e5, 0.0, 0.0)]);
        let settings = RenderSettings::default();
        let lut = BlackbodyLut::new(settings.brightness, settings.reference_temperature_k);
        let c = FlameConfig::default();
        for bad in [0.0, -1.0, f64::NAN, 11.0] {
            assert!(matches!(
                voxelize(sim.particles(), &c, &settings, &lut, bad),
                Err(VolumeError::VoxelSize(_))
            ));
        }
        assert!(matches!(
            voxelize(sim.particles(), &c, &settings, &lut, 0.001),
            Err(VolumeError::Extent { .. })
        ));
    }

    /// At 0.1 mm one particle's support spans ~10⁶ leaves: refused at once, before the
    /// (leaf, particle) list (8 GB for the paper's flame) is made, by `voxelize` and by
    /// the estimate alike.
    #[test]
    fn tiny_voxels_are_refused_before_any_list_is_made() {
        let sim = sim_with(vec![Vec3::ZERO; 3]);
        let settings = RenderSettings::default();
        let lut = BlackbodyLut::new(settings.brightness, settings.reference_temperature_k);
        let c = FlameConfig::default();
        assert!(matches!(
            voxelize(sim.particles(), &c, &settings, &lut, 1e-4),
            Err(VolumeError::TooLarge { .. })
        ));
        assert!(matches!(volume_bytes(30_000, &c, 1e-4), Err(VolumeError::TooLarge { .. })));
        assert!(matches!(volume_bytes(30_000, &c, f64::NAN), Err(VolumeError::VoxelSize(_))));
    }

    /// The estimate bounds what a frame's volume holds: its leaves' voxels (20 bytes
    /// each in the grids) and the (leaf, particle) entries.
    #[test]
    fn the_estimate_bounds_the_volume() {
        let mut sim = FlameSim::new(FlameConfig::default(), 3).unwrap();
        for _ in 0..30 {
            sim.step().unwrap();
        }
        let settings = RenderSettings::default();
        let lut = BlackbodyLut::new(settings.brightness, settings.reference_temperature_k);
        for voxel_m in [0.01, 0.005] {
            let v = voxelize(sim.particles(), sim.config(), &settings, &lut, voxel_m).unwrap();
            let leaves = v.density.leaves().count() as u64;
            let bound = volume_bytes(sim.particles().len(), sim.config(), voxel_m).unwrap();
            assert!(leaves * 512 * 20 * 2 <= bound, "{voxel_m}: {leaves} leaves, bound {bound} bytes");
        }
    }

    /// The slabs are independent: the grids of 1 and 3 threads are bit-identical.
    #[test]
    fn thread_count_does_not_change_the_grids() {
        let mut sim = FlameSim::new(FlameConfig::default(), 3).unwrap();
        for _ in 0..20 {
            sim.step().unwrap();
        }
        let settings = RenderSettings::default();
        let lut = BlackbodyLut::new(settings.brightness, settings.reference_temperature_k);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
                let v = voxelize(sim.particles(), sim.config(), &settings, &lut, 0.01).unwrap();
                phenomena_core::vdb::encode(
                    &[(&v.density).into(), (&v.temperature).into(), (&v.emission).into()],
                    &phenomena_core::vdb::Metadata::new(),
                )
            })
        };
        assert_eq!(run(1), run(3));
    }

    /// The air's `velocity` grid holds the air's velocity at the centre of every voxel
    /// inside its cylinder and nothing outside it; the hot gas rises above the burner
    /// and the air flows in towards the axis beside its base.
    #[test]
    fn the_air_velocity_grid_is_the_air_at_its_voxels() {
        let mut config = FlameConfig::default();
        config.extended.air.enabled = true;
        let inflow_m_s = config.extended.air.inflow_m_s;
        let mut sim = FlameSim::new(config, 3).unwrap();
        for _ in 0..60 {
            sim.step().unwrap();
        }
        let air = sim.air().expect("the air is on");
        let grid = air_velocity(air).unwrap();
        let (nr, nz, dx) = air.grid().shape();
        assert_eq!(grid.name(), "velocity");
        assert_eq!(grid.transform().voxel_size_m(), f64::from(dx));
        let (lo, hi) = air.bounds();
        let (lo, hi) = ((lo / dx).floor().as_ivec3().to_array(), (hi / dx).ceil().as_ivec3().to_array());
        let (mut inside, mut active) = (0u64, 0u64);
        for x in lo[0] - 1..=hi[0] + 1 {
            for y in lo[1] - 1..=hi[1] + 1 {
                for z in lo[2] - 1..=hi[2] + 1 {
                    let p = Vec3::new(x as f32, y as f32, z as f32) * dx;
                    let v = grid.get([x, y, z]);
                    if air.contains(p) {
                        inside += 1;
                        assert_eq!(v, air.velocity_at(p).to_array(), "voxel {x} {y} {z}");
                    } else {
                        assert_eq!(v, [0.0; 3], "voxel {x} {y} {z} outside the cylinder");
                    }
                    active += u64::from(v != [0.0; 3]);
                }
            }
        }
        // The cylinder's volume in voxels, within the voxels its surface cuts (a
        // shell one voxel thick: 2πR·H + 2πR² voxel areas).
        let (radius, height) = (nr as f64, nz as f64);
        let volume = std::f64::consts::PI * radius * radius * height;
        let shell = 2.0 * std::f64::consts::PI * radius * (height + radius);
        assert!((inside as f64 - volume).abs() < shell, "{inside} voxels inside, cylinder {volume:.0}");
        assert_eq!(grid.active_voxel_count(), active);
        // Above the burner's centre the gas rises; beside the base the air moves in.
        let origin = sim.config().emitter.position_m;
        let radius_m = sim.config().emitter.radius_m;
        let up =
            grid.get(((origin + Vec3::new(0.0, 2.0 * radius_m, 0.0)) / dx).round().as_ivec3().to_array());
        // Buoyancy has sped it up from the speed it entered at.
        assert!(up[1] > 2.0 * inflow_m_s, "the gas above the burner rises at {} m/s", up[1]);
        let side = (origin + Vec3::new(2.0 * radius_m, dx, 0.0)) / dx;
        let inflow = grid.get(side.round().as_ivec3().to_array());
        assert!(inflow[0] < 0.0, "the air beside the base moves in: {inflow:?}");
    }
}
