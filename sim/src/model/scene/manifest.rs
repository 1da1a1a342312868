//! `scene.toml`: the manifest of a scene folder (name, provenance, triangle count, sky and camera),
//! as in `../shared/scenes/*/scene.toml`.

use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use super::{Camera, SceneError};

/// The camera table of a manifest (`[camera]`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub look_at: [f32; 3],
    /// Up vector.
    pub up: [f32; 3],
    /// Vertical field of view in degrees, in `(0, 180)`.
    pub fov_y_deg: f32,
}

impl CameraSpec {
    /// The scene camera this table describes.
    pub fn camera(&self) -> Camera {
        Camera {
            eye: Vec3::from(self.eye),
            look_at: Vec3::from(self.look_at),
            up: Vec3::from(self.up),
            fov_y_deg: self.fov_y_deg,
        }
    }
}

/// A parsed and checked `scene.toml`. Unknown keys are rejected so that a misspelt key is an error
/// rather than silently ignored.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Short scene name (e.g. `SHIP`); the folder name is used when absent.
    pub name: Option<String>,
    /// Human-readable title.
    pub title: Option<String>,
    /// Provenance of the geometry.
    pub source: Option<String>,
    /// Whether every part of the original scene is present.
    pub complete: Option<bool>,
    /// Triangle count after triangulation, as recorded by whoever wrote the manifest.
    pub triangles: Option<u64>,
    /// Whether rays that miss see a sky gradient (default `true`).
    #[serde(default = "sky_default")]
    pub sky: bool,
    /// The camera: required unless a glTF file of the folder has a camera (which is then used
    /// instead, see [`super::load::load_folder`]).
    pub camera: Option<CameraSpec>,
}

/// The default of [`Manifest::sky`].
fn sky_default() -> bool {
    true
}

impl Manifest {
    /// Parse and check the text of a manifest; `path` names the file in errors.
    ///
    /// Errors ([`SceneError::Parse`], one line, with a line number where TOML gives one): TOML
    /// syntax, a missing camera key in `[camera]`, a wrong type, an unknown key, a non-finite
    /// camera number, a field of view outside `(0, 180)` degrees, or a degenerate camera frame.
    /// A manifest without `[camera]` parses; the folder's loader decides whether it needs one.
    pub fn parse(text: &str, path: &Path) -> Result<Manifest, SceneError> {
        let manifest: Manifest = toml::from_str(text).map_err(|e| {
            let message = e.message().trim().replace('\n', "; ");
            // A span over the whole text (e.g. a missing top-level key) has no useful line.
            let reason = match e.span().filter(|s| s.start > 0 || s.end < text.len()) {
                Some(span) => {
                    let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
                    format!("line {line}: {message}")
                }
                None => message,
            };
            parse_error(path, format!("invalid scene manifest: {reason}"))
        })?;
        if let Some(camera) = &manifest.camera {
            camera
                .camera()
                .check()
                .map_err(|reason| parse_error(path, format!("invalid [camera]: {reason}")))?;
        }
        Ok(manifest)
    }

    /// Read, parse and check the manifest file at `path` (see [`Manifest::parse`]).
    pub fn read(path: &Path) -> Result<Manifest, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Io {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        Manifest::parse(&text, path)
    }
}

/// A [`SceneError::Parse`] for `path`.
fn parse_error(path: &Path, reason: String) -> SceneError {
    SceneError::Parse {
        path: path.display().to_string(),
        reason,
    }
}
