//! The aurora as volumes: one emission grid per line, from the particles and
//! the line altitude profiles of the physical mode, for OpenVDB files a 3-D scene or a
//! planetarium's 3-D Earth renders.
//!
//! Geometry is the sky view's (`sky.rs`): the simulation plane lies at the top altitude,
//! centred over the origin, each particle the foot of a field line running down along B.
//! Every particle stands for the footprint 1/δ0 (the rest density of the current field)
//! and carries the column brightness of each line spread over altitude by that line's
//! volume emission profile (`deposition.rs`'s [`ColumnModel`]), so a voxel holds
//!
//! V(voxel) = Σ over particles whose field line crosses it of
//! gain × (footprint / voxel area) × ver(line, altitude) × 1e-4,
//!
//! each particle's foot and gain where and as the sky view draws it (the small-scale
//! motion, [`crate::small_scale`]: 1 with it off),
//! up to the top altitude (the share of a line emitted above it, some of the 630.0 nm
//! line's, is left out), in rayleighs per metre of path (ver in photons cm⁻³ s⁻¹: 1 m of it is 100 · ver
//! photons cm⁻² s⁻¹, 1e-4 · ver R). Integrated along a ray in metres it gives rayleighs,
//! the unit of the EXR line layers. The 630.0 nm afterglow of the images (the lingering
//! of O(¹D)) is not in the volume: it is this frame's emission.
//!
//! World space is metres (the sky view's km × 1000): x west, y altitude, z north; voxel
//! (i, j, k) is centred at (i, j, k) × voxel size. The five grids are filled in parallel,
//! each in a fixed order, so the bytes do not depend on the thread count.

use phenomena_core::vdb::{Grid, GridClass, Transform, VdbError};
use rayon::prelude::*;

use crate::deposition::ColumnModel;
use crate::emission::Line;
use crate::render::LINE_LAYERS;
use crate::sim::AuroraSim;
use crate::sky::{SkySettings, small_scale_now};

/// Why the volumes cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VolumeError {
    /// Paper mode has no altitude profiles.
    #[error(
        "the aurora's volumes come from the physical mode's altitude profiles: set [render.sky] mode = \"physical\""
    )]
    PaperMode,
    /// The plane view has no sky geometry.
    #[error("the aurora's volumes are made in the sky view: set [render] view = \"sky\"")]
    PlaneView,
    /// The voxel size is not usable.
    #[error("voxel size {0} km: expected a finite size in [0.05, 50] km")]
    VoxelSize(f64),
    /// The volumes would need too many voxels at this size.
    #[error(
        "the aurora's volumes at {voxel_km} km voxels would span up to {voxels} voxels (at most {MAX_VOXELS}): use larger voxels"
    )]
    TooLarge {
        /// Voxels the five grids may need.
        voxels: u64,
        /// The voxel size, km.
        voxel_km: f64,
    },
    /// The grid refused a value.
    #[error(transparent)]
    Grid(#[from] VdbError),
}

/// Most voxels the five grids of one frame may span together (4 bytes each in the
/// grids and about as much encoded: 2^28 voxels is 2 GiB).
pub const MAX_VOXELS: u64 = 1 << 28;

/// Bytes the five line grids of `sim`'s particles now take at `voxel_km` (grids and
/// their encoding), an upper bound from the leaf columns the particles' feet fall in,
/// the leaf layers of the profiles and the field's drift; refused like
/// [`line_volumes`] (a bad size, more than [`MAX_VOXELS`]) without making anything.
pub fn volume_bytes(
    sim: &AuroraSim,
    settings: &SkySettings,
    column: &ColumnModel,
    voxel_km: f64,
) -> Result<u64, VolumeError> {
    Ok(leaf_bound(sim, settings, column, voxel_km)? * 512 * 5 * 4 * 2)
}

/// The most leaves one of the five grids can hold (see [`volume_bytes`]), refused over
/// [`MAX_VOXELS`].
fn leaf_bound(
    sim: &AuroraSim,
    settings: &SkySettings,
    column: &ColumnModel,
    voxel_km: f64,
) -> Result<u64, VolumeError> {
    if !(voxel_km.is_finite() && (0.05..=50.0).contains(&voxel_km)) {
        return Err(VolumeError::VoxelSize(voxel_km));
    }
    let h = voxel_km;
    let mut leaf_columns: Vec<(i32, i32)> =
        feet(sim, h).into_iter().map(|(x, z, _)| (x >> 3, z >> 3)).collect();
    leaf_columns.sort_unstable();
    leaf_columns.dedup();
    let top = f64::from(settings.top_altitude_km);
    let layers = layers(column, h, top);
    let leaf_layers = match (layers.first(), layers.last()) {
        (Some(a), Some(b)) => ((b.0 >> 3) - (a.0 >> 3) + 1) as u64,
        _ => 0,
    };
    // Down one leaf layer (8 voxels) a field line drifts by `drift` leaves sideways.
    let (_, drift) = settings.field();
    let spread = |d: f64| d.abs().ceil() as u64 + 1;
    let leaves = (leaf_columns.len() as u64)
        .saturating_mul(leaf_layers)
        .saturating_mul(spread(drift.x))
        .saturating_mul(spread(drift.z));
    let voxels = leaves.saturating_mul(512 * 5);
    if voxels > MAX_VOXELS {
        return Err(VolumeError::TooLarge { voxels, voxel_km });
    }
    Ok(leaves)
}

/// The voxel column (x, z) of each particle's foot where the sky view draws it, and its
/// brightness factor (the small-scale motion, [`crate::small_scale`]), the plane
/// centred over the origin at voxels of `h` km (particles that are not finite or are
/// dark left out), in particle order.
fn feet(sim: &AuroraSim, h: f64) -> Vec<(i32, i32, f32)> {
    let grid = sim.grid();
    let centre = grid.origin_km + grid.extent_km() * 0.5;
    let small = small_scale_now(sim);
    sim.particles()
        .position_km
        .iter()
        .filter(|p| p.is_finite())
        .map(|&p| small.as_ref().map_or((p, 1.0), |s| s.apply(p)))
        .filter(|&(p, gain)| p.is_finite() && gain > 0.0)
        .map(|(p, gain)| {
            let q = p - centre;
            ((f64::from(q.x) / h).round() as i32, (f64::from(q.y) / h).round() as i32, gain)
        })
        .collect()
}

/// Altitudes where a line's emission is below this share of its peak are left empty.
pub const CUTOFF: f64 = 1e-4;

/// The grid names, in [`Line::ALL`] order: the EXR layer names without `.Y`
/// (`aurora_557_7`).
pub fn grid_names() -> [&'static str; 5] {
    LINE_LAYERS.map(|n| n.strip_suffix(".Y").unwrap_or(n))
}

/// The five line grids of `sim`'s current particles at `voxel_km` voxels, with the
/// column model and geometry of `settings` (see the module docs).
pub fn line_volumes(
    sim: &AuroraSim,
    settings: &SkySettings,
    column: &ColumnModel,
    voxel_km: f64,
) -> Result<[Grid<f32>; 5], VolumeError> {
    leaf_bound(sim, settings, column, voxel_km)?;
    let transform = Transform::new(voxel_km * 1e3, [0.0; 3])?;
    let h = voxel_km;
    // The particles' feet, their brightness summed per voxel column (sorted: a fixed
    // order, so the sums do not depend on the particles' order).
    let mut feet = feet(sim, h);
    feet.sort_unstable_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)).then(a.2.total_cmp(&b.2)));
    let mut columns: Vec<(i32, i32, f64)> = Vec::new();
    for f in feet {
        match columns.last_mut() {
            Some(c) if (c.0, c.1) == (f.0, f.1) => c.2 += f64::from(f.2),
            _ => columns.push((f.0, f.1, f64::from(f.2))),
        }
    }
    let footprint_km2 = 1.0 / f64::from(sim.field().rest_density.max(1e-12));
    let coverage = footprint_km2 / (h * h);
    let top = f64::from(settings.top_altitude_km);
    let (_, drift) = settings.field();
    let layers = layers(column, h, top);
    let mut grids: Vec<Grid<f32>> =
        grid_names().iter().map(|name| Grid::new(*name, transform, GridClass::FogVolume)).collect();
    grids.par_iter_mut().zip(Line::ALL).try_for_each(|(g, line)| -> Result<(), VolumeError> {
        g.insert_metadata("units", "R/m (rayleigh per metre of path)")?;
        g.insert_metadata("wavelength_nm", line.wavelength_nm())?;
        let profile = profile(column, line, &layers);
        for &(ix, iz, count) in &columns {
            let weight = coverage * count;
            for &(j, altitude_km, v) in &profile {
                // Down the field line: the foot drifts by `drift` per km of descent.
                let shift = drift * (top - altitude_km) / h;
                let ijk = [ix + shift.x.round() as i32, j, iz + shift.z.round() as i32];
                g.add(ijk, (weight * v * 1e-4) as f32);
            }
        }
        Ok(())
    })?;
    let grids: [Grid<f32>; 5] = grids.try_into().map_err(|_| VolumeError::VoxelSize(voxel_km))?;
    Ok(grids)
}

/// The voxel layers (index, altitude km) from the column's lowest altitude up to the top.
fn layers(column: &ColumnModel, h: f64, top: f64) -> Vec<(i32, f64)> {
    let bottom = column.altitudes_km().first().copied().unwrap_or(top);
    let (j0, j1) = ((bottom / h).ceil() as i32, (top / h).floor() as i32);
    (j0..=j1).map(|j| (j, f64::from(j) * h)).collect()
}

/// `line`'s volume emission rate at each layer, photons cm⁻³ s⁻¹ (interpolated linearly
/// in the column's table), leaving out layers below [`CUTOFF`] of the peak.
fn profile(column: &ColumnModel, line: Line, layers: &[(i32, f64)]) -> Vec<(i32, f64, f64)> {
    let (z, v) = (column.altitudes_km(), column.volume_emission(line));
    let peak = v.iter().copied().fold(0.0, f64::max);
    if !(peak > 0.0) || z.len() < 2 {
        return Vec::new();
    }
    let at = |a: f64| {
        let k = z.partition_point(|&x| x <= a).clamp(1, z.len() - 1);
        let t = ((a - z[k - 1]) / (z[k] - z[k - 1])).clamp(0.0, 1.0);
        v[k - 1] + (v[k] - v[k - 1]) * t
    };
    layers.iter().map(|&(j, a)| (j, a, at(a))).filter(|&(_, _, value)| value >= CUTOFF * peak).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::AuroraConfig;
    use crate::deposition::ColumnModel;

    fn column(settings: &SkySettings) -> ColumnModel {
        ColumnModel::new(crate::atmosphere::Atmosphere::msis21(), &settings.precipitation, &settings.yields)
    }

    /// A vertical field line: each column of voxels under the particles integrates to the
    /// line's column brightness times the covered share of the voxel, the sum the sky
    /// view's images are made of (to the trapezoid-versus-midpoint difference of a 1 km
    /// sampling of a profile tabulated at 1 km: under 1 %).
    #[test]
    fn columns_integrate_to_the_line_brightness() {
        let mut config = AuroraConfig::default();
        config.motion.particles = 3000;
        // Every particle at full brightness (the small-scale motion scales each one).
        config.small_scale.enabled = false;
        let sim = AuroraSim::new(config, 1).unwrap();
        let settings = SkySettings::default();
        let col = column(&settings);
        let grids = line_volumes(&sim, &settings, &col, 1.0).unwrap();
        let n = sim.particles().len() as f64;
        let footprint = 1.0 / f64::from(sim.field().rest_density);
        for (g, line) in grids.iter().zip(Line::ALL) {
            // Σ voxels × 1000 m of path × voxel area 1 km² = brightness × footprint, R km².
            let sum: f64 = g.leaves().flat_map(|(_, l)| l.iter()).map(|&v| f64::from(v)).sum::<f64>() * 1e3;
            // The column below the plane at the top altitude (630.0 nm reaches above it).
            let below = col.fraction_below(line, f64::from(settings.top_altitude_km));
            let expected = col.column_photons_cm2_s(line) * below / 1e6 * footprint * n;
            assert!((sum - expected).abs() <= 0.01 * expected, "{line:?}: {sum} vs {expected}");
            assert_eq!(g.name(), grid_names()[line.index()]);
        }
        assert!(grids[2].active_voxel_count() > 0);
    }

    #[test]
    fn bad_voxel_sizes_are_refused() {
        let mut config = AuroraConfig::default();
        config.motion.particles = 500;
        let sim = AuroraSim::new(config, 1).unwrap();
        let settings = SkySettings::default();
        let col = column(&settings);
        for bad in [0.0, 0.01, 51.0, f64::NAN] {
            assert!(matches!(line_volumes(&sim, &settings, &col, bad), Err(VolumeError::VoxelSize(_))));
        }
    }
}
