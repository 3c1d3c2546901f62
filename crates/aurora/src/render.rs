//! The aurora's renderer: the sky view ([`crate::sky`], thesis §2.4) or the plane view
//! ([`crate::plane`]), chosen by [`RenderSettings::view`], behind the one renderer shape
//! of every phenomenon (`new(settings, width, height, background)`, `render(&sim)`).

use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::phenomenon::Layer;
use serde::{Deserialize, Serialize};

use crate::plane::{PlaneView, render_plane};
use crate::sim::AuroraSim;
use crate::sky::{SkyRenderer, SkySettings, SkyTimings};
pub use phenomena_core::phenomenon::RenderError;

/// What an aurora scene's frames show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AuroraView {
    /// The aurora as a camera sees it ([`crate::sky`]).
    #[default]
    Sky,
    /// The x-z simulation plane from above.
    Plane,
}

/// Render settings of an aurora scene (`[render]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderSettings {
    /// What the frames show.
    pub view: AuroraView,
    /// The plane view's layers.
    pub plane: PlaneView,
    /// The sky view.
    pub sky: SkySettings,
}

/// EXR channel names of the five line images, in [`crate::emission::Line::ALL`] order
/// (`aurora_557_7.Y`, ...).
pub const LINE_LAYERS: [&str; 5] =
    ["aurora_391_4.Y", "aurora_427_8.Y", "aurora_557_7.Y", "aurora_630_0.Y", "aurora_670_5.Y"];

/// Draws an [`AuroraSim`] in the view its settings choose.
pub struct AuroraRenderer {
    settings: RenderSettings,
    target: Target,
}

enum Target {
    Sky(Box<SkyRenderer>),
    Plane(Frame),
}

impl AuroraRenderer {
    /// Whether [`AuroraRenderer::new`] accepts `settings` at `width × height` (besides
    /// the background image), without building anything.
    pub fn check(settings: &RenderSettings, width: usize, height: usize) -> Result<(), RenderError> {
        match settings.view {
            AuroraView::Sky => SkyRenderer::check(&settings.sky, width, height),
            AuroraView::Plane => phenomena_core::phenomenon::check_size(width, height),
        }
    }

    /// A renderer of `width × height` frames; `background` is the loaded image when the
    /// sky view's settings ask for one (see [`SkyRenderer::new`]).
    pub fn new(
        settings: RenderSettings,
        width: usize,
        height: usize,
        background: Option<&Frame>,
    ) -> Result<Self, RenderError> {
        let target = match settings.view {
            AuroraView::Sky => {
                Target::Sky(Box::new(SkyRenderer::new(settings.sky.clone(), width, height, background)?))
            }
            AuroraView::Plane => {
                phenomena_core::phenomenon::check_size(width, height)?;
                Target::Plane(Frame::new(width, height))
            }
        };
        Ok(Self { settings, target })
    }

    /// The settings.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// Render `sim`'s current state (linear sRGB).
    pub fn render(&mut self, sim: &AuroraSim) -> &Frame {
        match &mut self.target {
            Target::Sky(sky) => sky.render(sim),
            Target::Plane(frame) => {
                *frame = render_plane(sim, frame.width(), frame.height(), &self.settings.plane);
                frame
            }
        }
    }

    /// The frame of the last [`AuroraRenderer::render`].
    pub fn frame(&self) -> &Frame {
        match &self.target {
            Target::Sky(sky) => sky.frame(),
            Target::Plane(frame) => frame,
        }
    }

    /// The sky renderer, in the sky view.
    pub fn sky(&self) -> Option<&SkyRenderer> {
        match &self.target {
            Target::Sky(sky) => Some(sky),
            Target::Plane(_) => None,
        }
    }

    /// Where the last sky render's time went (`None` in the plane view).
    pub fn timings(&self) -> Option<SkyTimings> {
        self.sky().map(SkyRenderer::timings)
    }

    /// Time the sky view's parts with `clock` (the library reads no clock itself).
    pub fn set_clock(&mut self, clock: SharedClock) {
        if let Target::Sky(sky) = &mut self.target {
            sky.set_clock(clock);
        }
    }

    /// A preview extension: emit for one particle in `stride` only (see
    /// [`SkyRenderer::set_particle_subset`]); no effect in the plane view.
    pub fn set_particle_subset(&mut self, stride: usize, phase: usize) {
        if let Target::Sky(sky) = &mut self.target {
            sky.set_particle_subset(stride, phase);
        }
    }
}

impl AuroraRenderer {
    /// The five line volumes of `sim` now at `voxel_km` ([`crate::volume`]): the sky
    /// view's geometry and the physical mode's altitude profiles.
    pub fn line_volumes(
        &self,
        sim: &AuroraSim,
        voxel_km: f64,
    ) -> Result<[phenomena_core::vdb::Grid<f32>; 5], crate::volume::VolumeError> {
        let sky = match &self.target {
            Target::Sky(sky) => sky,
            Target::Plane(_) => return Err(crate::volume::VolumeError::PlaneView),
        };
        let column = sky.column_model().ok_or(crate::volume::VolumeError::PaperMode)?;
        crate::volume::line_volumes(sim, sky.settings(), column, voxel_km)
    }

    /// Bytes [`AuroraRenderer::line_volumes`] of `sim` now takes at `voxel_km` (an upper
    /// bound, [`crate::volume::volume_bytes`]).
    pub fn volume_bytes(&self, sim: &AuroraSim, voxel_km: f64) -> Result<u64, crate::volume::VolumeError> {
        let sky = match &self.target {
            Target::Sky(sky) => sky,
            Target::Plane(_) => return Err(crate::volume::VolumeError::PlaneView),
        };
        let column = sky.column_model().ok_or(crate::volume::VolumeError::PaperMode)?;
        crate::volume::volume_bytes(sim, sky.settings(), column, voxel_km)
    }
}

impl phenomena_core::phenomenon::Renderer<AuroraSim> for AuroraRenderer {
    fn render(&mut self, sim: &AuroraSim) -> &Frame {
        AuroraRenderer::render(self, sim)
    }

    fn frame(&self) -> &Frame {
        AuroraRenderer::frame(self)
    }

    /// The five line images of the sky view (rayleighs in `physical` mode), named by
    /// [`LINE_LAYERS`]; none in the plane view.
    fn layers(&self) -> Vec<Layer<'_>> {
        let Some(sky) = self.sky() else { return Vec::new() };
        LINE_LAYERS.iter().zip(sky.line_images()).map(|(name, plane)| Layer { name, plane }).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emission::Line;

    #[test]
    fn layer_names_follow_the_wavelengths() {
        for (name, line) in LINE_LAYERS.iter().zip(Line::ALL) {
            let expect = format!("aurora_{}.Y", format!("{:.1}", line.wavelength_nm()).replace('.', "_"));
            assert_eq!(*name, expect);
        }
    }
}
