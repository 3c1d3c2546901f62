//! The `[scene]` table every scene file shares.

use phenomena_core::tonemap::{Exposure, ToneMap};
use phenomena_core::validate::Issues;
use serde::{Deserialize, Serialize};

/// Largest frame side, pixels.
pub const MAX_SIDE_PX: u32 = 16384;

/// Settings every scene shares (`[scene]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneSettings {
    /// Number of frames to render.
    pub frames: u32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Exposure compensation in stops, applied before tone mapping (PNG only).
    pub exposure_ev: f32,
    /// Tone-mapping operator for PNG output.
    pub tone_map: ToneMap,
}

impl Default for SceneSettings {
    fn default() -> Self {
        Self { frames: 120, width: 1280, height: 720, seed: 1, exposure_ev: 0.0, tone_map: ToneMap::Aces }
    }
}

impl SceneSettings {
    /// The exposure and tone map of PNG output.
    pub fn exposure(&self) -> Exposure {
        Exposure { ev: self.exposure_ev, tone_map: self.tone_map }
    }

    /// Every problem, with paths from the file's root (`scene.width`).
    pub fn validate(&self, i: &mut Issues) {
        i.count("scene.frames", u64::from(self.frames), 1..=1_000_000);
        i.count("scene.width", u64::from(self.width), 1..=u64::from(MAX_SIDE_PX));
        i.count("scene.height", u64::from(self.height), 1..=u64::from(MAX_SIDE_PX));
        i.range("scene.exposure_ev", self.exposure_ev, -32.0..=32.0);
        // TOML integers are signed 64-bit: a larger seed could not be saved.
        i.count("scene.seed", self.seed, 0..=i64::MAX as u64);
    }

    /// Width and height as sizes.
    pub fn size(&self) -> (usize, usize) {
        (self.width as usize, self.height as usize)
    }
}
