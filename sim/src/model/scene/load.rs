//! Resolving a scene spec (built-in name, scene file, scene folder or shared scene name) to a
//! loaded [`Scene`], and listing the scenes available for `vtq scenes`.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::builtin::{builtin, builtin_counts, builtin_title, BUILTIN_NAMES};
use super::geometry::SceneGeometry;
use super::gltf::read_gltf_file;
use super::manifest::Manifest;
use super::obj::ObjReader;
use super::ply::read_ply_file;
use super::report::LoadReport;
use super::{Camera, Scene, SceneError};

/// File name of a scene folder's manifest.
pub const MANIFEST_FILE: &str = "scene.toml";

/// A loaded scene and its [`LoadReport`].
#[derive(Debug, Clone)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// What loading read but did not use, left out or could not find.
    pub report: LoadReport,
}

/// Load the scene `spec` names (see [`load_scene_with_report`]) without its report.
pub fn load_scene(spec: &str) -> Result<Scene, SceneError> {
    load_scene_with_report(spec).map(|loaded| loaded.scene)
}

/// Load the scene `spec` names, trying in order:
/// 1. a built-in name (`wknd`, `cornell`, `city` or `city:N`; ASCII case-insensitive; a
///    malformed `city:N` is a [`SceneError::Parse`] naming the spec);
/// 2. an existing path: a scene file (`.obj`, `.gltf`, `.glb` or `.ply`; see
///    [`load_scene_file`]), a scene folder (every scene file in it, sorted by file name, in one
///    world space, camera and sky as [`load_folder`] says) or a `scene.toml` file (its folder);
/// 3. a bare name (no path separator): a folder of that name, or whose manifest `name` is that
///    name (ASCII case-insensitive, e.g. `SPNZA`), in the shared scenes folders
///    (see [`shared_scenes_dir`]).
///
/// Errors name the file: [`SceneError::Io`] for a path that does not exist or cannot be read,
/// [`SceneError::Parse`] for malformed OBJ/MTL/glTF/PLY/manifest contents (with a line number
/// where known), a folder without scene files, a scene without faces or without a camera where
/// one is needed, [`SceneError::Unknown`] for a
/// bare name nothing matches. Loading does not print: statements read but not used, triangles
/// left out for non-finite vertices, missing `.mtl` libraries (their faces use the default
/// material), undefined material names and a manifest triangle count that differs from the
/// files are in the [`LoadReport`]. The scene passes [`Scene::validate`].
pub fn load_scene_with_report(spec: &str) -> Result<LoadedScene, SceneError> {
    if let Some(scene) = builtin(spec) {
        return scene.map(|scene| LoadedScene {
            scene,
            report: LoadReport::default(),
        });
    }
    if spec.is_empty() {
        return Err(SceneError::Unknown(String::new()));
    }
    let path = Path::new(spec);
    if path.exists() {
        return load_path(path);
    }
    let bare = !spec.contains(['/', '\\']) && spec != "." && spec != "..";
    if bare {
        for dir in shared_scenes_dirs() {
            if let Some(folder) = find_shared_scene(&dir, spec) {
                return load_folder(&folder);
            }
        }
    }
    if bare && path.extension().is_none() {
        Err(SceneError::Unknown(spec.to_string()))
    } else {
        Err(SceneError::Io {
            path: spec.to_string(),
            reason: "no such file or folder".into(),
        })
    }
}

/// Load an existing path: a folder, a `scene.toml` (its folder) or a scene file.
fn load_path(path: &Path) -> Result<LoadedScene, SceneError> {
    if path.is_dir() {
        return load_folder(path);
    }
    if path.file_name().is_some_and(|n| n == MANIFEST_FILE) {
        return load_folder(path.parent().unwrap_or(Path::new(".")));
    }
    if FileKind::of(path).is_some() {
        return load_scene_file(path);
    }
    Err(SceneError::Parse {
        path: path.display().to_string(),
        reason: "not a scene: expected a .obj, .gltf, .glb or .ply file, a scene folder or a \
                 scene.toml"
            .into(),
    })
}

/// The formats of scene files, by extension (ASCII case-insensitive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FileKind {
    /// `.obj` (with its `.mtl` libraries).
    Obj,
    /// `.gltf` or `.glb`.
    Gltf,
    /// `.ply`.
    Ply,
}

impl FileKind {
    /// The format of `path`, or `None` when its extension names none.
    fn of(path: &Path) -> Option<FileKind> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(FileKind::Obj),
            "gltf" | "glb" => Some(FileKind::Gltf),
            "ply" => Some(FileKind::Ply),
            _ => None,
        }
    }
}

/// Scene files appended into one world space, with the first glTF camera met.
#[derive(Default)]
struct SceneFiles {
    /// The geometry so far.
    geometry: SceneGeometry,
    /// Reads OBJ files (each material library once).
    obj: ObjReader,
    /// The first glTF camera and its file.
    gltf_camera: Option<(Camera, PathBuf)>,
    /// Whether a glTF file was read.
    any_gltf: bool,
}

impl SceneFiles {
    /// Append the scene file at `path`, of format `kind`.
    fn load(&mut self, path: &Path, kind: FileKind) -> Result<(), SceneError> {
        match kind {
            FileKind::Obj => {
                self.obj.load_file(&mut self.geometry, path)?;
            }
            FileKind::Gltf => {
                let file = read_gltf_file(path)?;
                self.geometry.add_part(&file.part, path)?;
                self.geometry.gltf_ignored.merge(&file.ignored);
                if self.gltf_camera.is_none() {
                    self.gltf_camera = file.camera.map(|c| (c, path.to_path_buf()));
                }
                self.any_gltf = true;
            }
            FileKind::Ply => {
                let file = read_ply_file(path)?;
                self.geometry.add_part(&file.part, path)?;
                self.geometry.ply_ignored.merge(&file.ignored);
            }
        }
        Ok(())
    }
}

/// Load one scene file as a scene named after the file stem, sky on: a `.obj` (and its `.mtl`
/// libraries) or `.ply` file with a camera framing its bounds ([`Camera::framing`]), a `.gltf`
/// or `.glb` file with its first perspective camera, or framing its bounds when it has none (as
/// most of the Khronos sample models; [`LoadReport::framed_camera`] says so).
pub fn load_scene_file(path: &Path) -> Result<LoadedScene, SceneError> {
    let kind = FileKind::of(path).ok_or_else(|| SceneError::Parse {
        path: path.display().to_string(),
        reason: "not a scene file: expected .obj, .gltf, .glb or .ply".into(),
    })?;
    let mut files = SceneFiles::default();
    files.load(path, kind)?;
    let name = path
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    let framed = files.any_gltf && files.gltf_camera.is_none();
    let camera = files.gltf_camera.map(|(camera, _)| camera);
    let mut loaded = scene_from_geometry(files.geometry, path, name, camera, true)?;
    loaded.report.framed_camera = framed;
    Ok(loaded)
}

/// Load a scene folder: every scene file in it (`.obj`, `.gltf`, `.glb`, `.ply`; not
/// recursive; extensions ASCII case-insensitive), sorted by file name, appended in that order
/// into one world space, with name and sky from `scene.toml` when present.
///
/// The camera is the first perspective camera of the glTF files (in that order), else the
/// manifest's `[camera]`; without either, a folder with a `scene.toml` is an error, and one
/// without gets a camera framing its bounds (reported in [`LoadReport::framed_camera`] when it
/// holds glTF files, which usually bring their own). A manifest camera that a glTF camera replaces is reported in
/// [`LoadReport::unused_manifest_camera`], and a manifest `triangles` count that differs from
/// the files' in [`LoadReport::manifest_mismatch`].
pub fn load_folder(dir: &Path) -> Result<LoadedScene, SceneError> {
    let manifest_path = dir.join(MANIFEST_FILE);
    let manifest = if manifest_path.is_file() {
        Some(Manifest::read(&manifest_path)?)
    } else {
        None
    };
    let parts = scene_files(dir)?;
    if parts.is_empty() {
        return Err(SceneError::Parse {
            path: dir.display().to_string(),
            reason: "the folder holds no scene files (.obj, .gltf, .glb or .ply)".into(),
        });
    }
    let mut files = SceneFiles::default();
    for (part, kind) in &parts {
        files.load(part, *kind)?;
    }
    let geometry = &files.geometry;
    let in_files = geometry.triangles.len() as u64 + geometry.nonfinite_triangles;
    let mismatch = manifest
        .as_ref()
        .and_then(|m| m.triangles)
        .filter(|&expected| expected != in_files)
        .map(|expected| (manifest_path.clone(), expected));
    let manifest_camera = manifest.as_ref().and_then(|m| m.camera);
    let mut unused_manifest_camera = None;
    let camera = match (files.gltf_camera, manifest_camera) {
        (Some((camera, gltf)), spec) => {
            if spec.is_some() {
                unused_manifest_camera = Some((manifest_path.clone(), gltf));
            }
            Some(camera)
        }
        (None, Some(spec)) => Some(spec.camera()),
        (None, None) if manifest.is_some() => {
            return Err(SceneError::Parse {
                path: manifest_path.display().to_string(),
                reason: "no [camera]: a scene.toml needs one unless a glTF file of the folder \
                         has a camera"
                    .into(),
            })
        }
        (None, None) => None,
    };
    let framed = camera.is_none() && files.any_gltf;
    let name = manifest
        .as_ref()
        .and_then(|m| m.name.clone())
        .unwrap_or_else(|| folder_name(dir));
    let sky = manifest.as_ref().is_none_or(|m| m.sky);
    let mut loaded = scene_from_geometry(files.geometry, dir, name, camera, sky)?;
    loaded.report.manifest_mismatch = mismatch;
    loaded.report.unused_manifest_camera = unused_manifest_camera;
    loaded.report.framed_camera = framed;
    Ok(loaded)
}

/// Build and check the scene loaded from `origin` (a file or folder, named in errors) from its
/// geometry, with `camera` (`None`: a camera framing the geometry) and `sky`, and its load
/// report.
///
/// Errors ([`SceneError::Parse`] naming `origin`): no triangles, or a scene that fails
/// [`Scene::validate`].
pub fn scene_from_geometry(
    geometry: SceneGeometry,
    origin: &Path,
    name: String,
    camera: Option<Camera>,
    sky: bool,
) -> Result<LoadedScene, SceneError> {
    if geometry.triangles.is_empty() {
        let reason = if geometry.nonfinite_triangles > 0 {
            format!(
                "no faces: all {} triangles use non-finite vertices",
                geometry.nonfinite_triangles
            )
        } else {
            "no faces: the scene has nothing to render".into()
        };
        return Err(SceneError::Parse {
            path: origin.display().to_string(),
            reason,
        });
    }
    let report = LoadReport::from_geometry(&geometry);
    // Every stored position is used by a triangle, so their bounds are the scene's.
    let camera = camera.unwrap_or_else(|| {
        let (min, max) = geometry.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(min, max), &p| (min.min(p), max.max(p)),
        );
        Camera::framing(min, max)
    });
    let scene = Scene {
        name,
        positions: geometry.positions,
        triangles: geometry.triangles,
        tri_material: geometry.tri_material,
        spheres: Vec::new(),
        materials: geometry.materials,
        camera,
        sky,
    };
    scene.validate().map_err(|e| match e {
        SceneError::Parse { reason, .. } => SceneError::Parse {
            path: origin.display().to_string(),
            reason,
        },
        other => other,
    })?;
    Ok(LoadedScene { scene, report })
}

/// The scene files directly in `dir` with their formats, sorted by file name.
fn scene_files(dir: &Path) -> Result<Vec<(PathBuf, FileKind)>, SceneError> {
    let entries = std::fs::read_dir(dir).map_err(|e| SceneError::Io {
        path: dir.display().to_string(),
        reason: e.to_string(),
    })?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|e| SceneError::Io {
                path: dir.display().to_string(),
                reason: e.to_string(),
            })?
            .path();
        if let Some(kind) = FileKind::of(&path).filter(|_| path.is_file()) {
            files.push((path, kind));
        }
    }
    files.sort_by(|a, b| a.0.file_name().cmp(&b.0.file_name()));
    Ok(files)
}

/// The last component of `dir` (after resolving `.` and `..`), for naming a scene.
fn folder_name(dir: &Path) -> String {
    let resolved = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    resolved
        .file_name()
        .map_or_else(|| "scene".into(), |n| n.to_string_lossy().into_owned())
}

/// The shared scenes folder (`../shared/scenes` from the project root), or `None` when absent.
/// Searched for as `shared/scenes` in each ancestor of, in order: the current directory, the
/// running executable, and this crate's source folder at build time. The first found wins.
pub fn shared_scenes_dir() -> Option<PathBuf> {
    shared_scenes_dirs().into_iter().next()
}

/// Every distinct shared scenes folder found, in [`shared_scenes_dir`]'s search order.
fn shared_scenes_dirs() -> Vec<PathBuf> {
    let mut starts = Vec::new();
    if let Ok(cwd) = std::env::current_dir() {
        starts.push(cwd);
    }
    if let Ok(exe) = std::env::current_exe() {
        starts.push(exe);
    }
    starts.push(PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    let mut found: Vec<PathBuf> = Vec::new();
    for start in starts {
        let hit = start
            .ancestors()
            .map(|a| a.join("shared").join("scenes"))
            .find(|c| c.is_dir())
            .and_then(|c| c.canonicalize().ok());
        if let Some(dir) = hit {
            if !found.contains(&dir) {
                found.push(dir);
            }
        }
    }
    found
}

/// The folder in `shared` whose name, or whose manifest's `name`, is `name` (ASCII
/// case-insensitive; an exact folder name first, then the first match in file-name order).
fn find_shared_scene(shared: &Path, name: &str) -> Option<PathBuf> {
    let exact = shared.join(name);
    if exact.is_dir() {
        return Some(exact);
    }
    scene_folders(shared).into_iter().find(|dir| {
        folder_name(dir).eq_ignore_ascii_case(name)
            || Manifest::read(&dir.join(MANIFEST_FILE))
                .ok()
                .and_then(|m| m.name)
                .is_some_and(|n| n.eq_ignore_ascii_case(name))
    })
}

/// The sub-folders of `shared` that hold a `scene.toml` or a scene file, sorted by name.
fn scene_folders(shared: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(shared) else {
        return Vec::new();
    };
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .filter(|p| p.join(MANIFEST_FILE).is_file() || scene_files(p).is_ok_and(|f| !f.is_empty()))
        .collect();
    dirs.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    dirs
}

/// Where a listed scene comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SceneKind {
    /// Generated in code ([`super::builtin`]).
    BuiltIn,
    /// A scene folder at this path.
    Folder(PathBuf),
}

/// How a listed scene's primitive counts were obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CountSource {
    /// Counted from the generated scene, or known exactly without generating it (a `city:N`
    /// scene has exactly N triangles).
    Loaded,
    /// Read from the manifest's `triangles` field without loading the geometry.
    Manifest,
    /// Not known without loading (no manifest, no `triangles` field, or a broken manifest).
    Unknown,
}

/// One entry of [`list_scenes`].
#[derive(Debug, Clone, PartialEq)]
pub struct SceneInfo {
    /// The spec to pass to [`load_scene`] (built-in name or folder name).
    pub name: String,
    /// The manifest's short name (e.g. `SPNZA`), or the built-in name.
    pub label: String,
    /// One-line description (manifest title, or a built-in's description).
    pub title: String,
    /// Built-in or folder.
    pub kind: SceneKind,
    /// Triangle count, if known (see `counted`).
    pub triangles: Option<usize>,
    /// Procedural sphere count (0 for folders: scene files hold none).
    pub spheres: usize,
    /// Where the counts come from.
    pub counted: CountSource,
    /// Whether the scene is complete (manifest `complete`); `None` when not stated.
    pub complete: Option<bool>,
    /// A problem found while listing (e.g. a manifest that does not parse), if any.
    pub problem: Option<String>,
}

impl SceneInfo {
    /// Number of primitives (triangles + spheres), if the triangle count is known.
    pub fn prims(&self) -> Option<usize> {
        self.triangles.map(|t| t + self.spheres)
    }
}

/// The built-in scenes (counted by generating them; the `city` family as one row with its
/// default budget, not generated) followed by the scene folders in [`shared_scenes_dir`] sorted
/// by folder name (counted from their manifests, not loaded).
pub fn list_scenes() -> Vec<SceneInfo> {
    let mut list: Vec<SceneInfo> = BUILTIN_NAMES
        .iter()
        .filter_map(|&name| {
            let (triangles, spheres) = builtin_counts(name)?;
            Some(SceneInfo {
                name: name.to_string(),
                label: name.to_string(),
                title: builtin_title(name).unwrap_or_default().to_string(),
                kind: SceneKind::BuiltIn,
                triangles: Some(triangles),
                spheres,
                counted: CountSource::Loaded,
                complete: Some(true),
                problem: None,
            })
        })
        .collect();
    if let Some(shared) = shared_scenes_dir() {
        list.extend(
            scene_folders(&shared)
                .into_iter()
                .map(|dir| folder_info(&dir)),
        );
    }
    list
}

/// The listing entry of one scene folder, from its manifest.
fn folder_info(dir: &Path) -> SceneInfo {
    let name = folder_name(dir);
    let mut info = SceneInfo {
        name: name.clone(),
        label: name,
        title: String::new(),
        kind: SceneKind::Folder(dir.to_path_buf()),
        triangles: None,
        spheres: 0,
        counted: CountSource::Unknown,
        complete: None,
        problem: None,
    };
    let manifest_path = dir.join(MANIFEST_FILE);
    if !manifest_path.is_file() {
        info.problem = Some(format!("no {MANIFEST_FILE}: glTF or default camera"));
        return info;
    }
    match Manifest::read(&manifest_path) {
        Ok(m) => {
            if let Some(label) = m.name {
                info.label = label;
            }
            info.title = m.title.unwrap_or_default();
            info.complete = m.complete;
            if let Some(t) = m.triangles.and_then(|t| usize::try_from(t).ok()) {
                info.triangles = Some(t);
                info.counted = CountSource::Manifest;
            }
        }
        Err(e) => info.problem = Some(e.to_string()),
    }
    info
}
