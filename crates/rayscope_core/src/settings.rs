//! Validated render settings: what the core needs to know, independent of any command line.

use serde::{Deserialize, Serialize};

use crate::camera::CameraSettings;
use crate::mistakes::Mistakes;

/// Which of the course's stages to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// Stage 1: the closest hit's material colour, one ray per pixel.
    One,
    /// Stage 2: Whitted ray tracing with point lights, mirrors and glass.
    Two,
    /// Everything rayscope supports (stage 2 plus every stage-3 add-on).
    #[default]
    Full,
}

/// What a pixel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Channel {
    /// The rendered colour.
    #[default]
    Color,
    /// The first hit's shading normal, mapped from [−1, 1] to [0, 1].
    Normal,
    /// Distance to the first hit, mapped to [0, 1] over the scene's depth range.
    Depth,
    /// A distinct colour per entity.
    Entity,
    /// The first hit's material colour (stage 1).
    Albedo,
    /// Number of BVH nodes and primitives tested for the camera ray, as a heat map.
    Cost,
}

/// Everything that decides what a render produces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RenderSettings {
    /// Image width in pixels (≥ 1).
    pub width: u32,
    /// Image height in pixels (≥ 1).
    pub height: u32,
    /// Anti-aliasing: an `aa` × `aa` grid of samples per pixel (`-x`, ≥ 1).
    pub aa: u32,
    /// Stage to render.
    pub stage: Stage,
    /// Ambient (indirect diffuse) lighting (`-l`).
    pub ambient: bool,
    /// Quality level for stochastic effects (`-q`).
    pub quality: u32,
    /// Most secondary bounces for mirrors and glass.
    pub max_depth: u32,
    /// Camera.
    pub camera: CameraSettings,
    /// Seed of every random stream.
    pub seed: u64,
    /// What pixels show.
    pub channel: Channel,
    /// The course's mistakes to make (`--mistake`); none for a correct render.
    #[serde(default, skip_serializing_if = "Mistakes::is_empty")]
    pub mistakes: Mistakes,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 400,
            height: 400,
            aa: 1,
            stage: Stage::Full,
            ambient: false,
            quality: 0,
            max_depth: 8,
            camera: CameraSettings::default(),
            seed: 0,
            channel: Channel::Color,
            mistakes: Mistakes::NONE,
        }
    }
}
