//! The load report: what loading a scene read but did not use, left out or could not find, so
//! that nothing is dropped unseen. The command line prints it under the scene summary.

use std::path::PathBuf;

use super::geometry::SceneGeometry;
use super::text::StatementCounts;

/// What a scene load read but did not use, left out or could not find (all empty for the
/// built-in scenes).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadReport {
    /// OBJ statements read but not used, by keyword (e.g. `vt`, `vn`, `o`, `s`, `l`).
    pub ignored: StatementCounts,
    /// MTL statements read but not used, by keyword (e.g. `map_Kd`, `Ka`, `bump`).
    pub mtl_ignored: StatementCounts,
    /// glTF content read but not used, by kind (e.g. `baseColorTexture`, `mode LINES`).
    pub gltf_ignored: StatementCounts,
    /// PLY properties and elements read but not used, by kind (e.g. `vertex red`, `edge`).
    pub ply_ignored: StatementCounts,
    /// Vertices whose position is not finite.
    pub nonfinite_vertices: u64,
    /// Triangles left out because a corner's position is not finite.
    pub nonfinite_triangles: u64,
    /// Material libraries named by `mtllib` that do not exist.
    pub missing_mtl: Vec<PathBuf>,
    /// Material names selected by `usemtl` that no loaded library defines.
    pub undefined_materials: Vec<String>,
    /// The manifest and its `triangles` count, when that count differs from the triangles in
    /// the files (loaded plus left out).
    pub manifest_mismatch: Option<(PathBuf, u64)>,
    /// The manifest whose `[camera]` was not used and the glTF file whose camera was, when both
    /// give one.
    pub unused_manifest_camera: Option<(PathBuf, PathBuf)>,
    /// glTF files were loaded but none has a perspective camera (and no `scene.toml` gives
    /// one): the camera frames the scene's bounds, as for OBJ and PLY files.
    pub framed_camera: bool,
}

impl LoadReport {
    /// The counts gathered by `geometry`.
    pub fn from_geometry(geometry: &SceneGeometry) -> LoadReport {
        LoadReport {
            ignored: geometry.ignored.clone(),
            mtl_ignored: geometry.mtl_ignored.clone(),
            gltf_ignored: geometry.gltf_ignored.clone(),
            ply_ignored: geometry.ply_ignored.clone(),
            nonfinite_vertices: geometry.nonfinite_vertices,
            nonfinite_triangles: geometry.nonfinite_triangles,
            missing_mtl: geometry.missing_mtl.clone(),
            undefined_materials: geometry.undefined_materials.clone(),
            manifest_mismatch: None,
            unused_manifest_camera: None,
            framed_camera: false,
        }
    }

    /// The one line naming every ignored statement with its count, e.g. `ignored: vt x12,
    /// l x3; in .mtl files: map_Kd x4; in glTF files: baseColorTexture x2; in .ply files:
    /// vertex red x8`, or `None` when nothing was ignored.
    pub fn ignored_line(&self) -> Option<String> {
        let mut parts = Vec::new();
        if !self.ignored.is_empty() {
            parts.push(self.ignored.to_string());
        }
        for (label, counts) in [
            ("in .mtl files", &self.mtl_ignored),
            ("in glTF files", &self.gltf_ignored),
            ("in .ply files", &self.ply_ignored),
        ] {
            if !counts.is_empty() {
                parts.push(format!("{label}: {counts}"));
            }
        }
        (!parts.is_empty()).then(|| format!("ignored: {}", parts.join("; ")))
    }

    /// The line counting what was left out for non-finite vertices, or `None`.
    pub fn left_out_line(&self) -> Option<String> {
        (self.nonfinite_vertices > 0).then(|| {
            format!(
                "left out: {} triangle{} using {} non-finite vert{} (nan, inf or w = 0)",
                self.nonfinite_triangles,
                if self.nonfinite_triangles == 1 {
                    ""
                } else {
                    "s"
                },
                self.nonfinite_vertices,
                if self.nonfinite_vertices == 1 {
                    "ex"
                } else {
                    "ices"
                },
            )
        })
    }

    /// The line saying the camera frames the scene because its glTF files have none
    /// ([`LoadReport::framed_camera`]), or `None`.
    pub fn camera_line(&self) -> Option<String> {
        self.framed_camera.then(|| {
            "camera: no glTF file has a perspective camera, so the camera frames the scene's \
             bounds (a scene.toml [camera] in its folder chooses another)"
                .to_string()
        })
    }

    /// Warnings (without a `warning:` prefix): missing libraries, undefined materials, a
    /// manifest count that differs from the files and a manifest camera a glTF camera replaced.
    pub fn warnings(&self, loaded_triangles: usize) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(first) = self.missing_mtl.first() {
            let n = self.missing_mtl.len();
            out.push(format!(
                "{n} material librar{} not found (first: {}); their faces use the default grey \
                 material",
                if n == 1 { "y" } else { "ies" },
                first.display()
            ));
        }
        if let Some(first) = self.undefined_materials.first() {
            let n = self.undefined_materials.len();
            out.push(format!(
                "{n} material name{} used by usemtl but defined in no library (first: '{first}'); \
                 their faces use the default grey material",
                if n == 1 { "" } else { "s" },
            ));
        }
        if let Some((manifest, expected)) = &self.manifest_mismatch {
            out.push(format!(
                "{} says {expected} triangles but the files hold {} ({loaded_triangles} loaded, \
                 {} left out)",
                manifest.display(),
                loaded_triangles as u64 + self.nonfinite_triangles,
                self.nonfinite_triangles
            ));
        }
        if let Some((manifest, gltf)) = &self.unused_manifest_camera {
            out.push(format!(
                "the [camera] of {} is not used: the camera of {} is",
                manifest.display(),
                gltf.display()
            ));
        }
        out
    }
}
