//! glTF 2.0 scenes: `.gltf` (JSON, buffers embedded as base64 `data:` URIs or in separate
//! files) and `.glb` (binary, buffers in its binary chunk), read with the `gltf` crate's
//! document model and vtq's own bounds-checked accessor reader (`gltf/accessor.rs`).
//!
//! # What is read
//! The JSON (a UTF-8 byte-order mark, which writers must not add, is ignored as the specification
//! allows) and the file's default scene (`scene`), else its first scene: every node reachable from
//! the scene's root nodes, depth first in file order, each with its world transform (its parents'
//! transforms times its own: `matrix`, or `translation * rotation * scale`). Of each node's mesh,
//! every primitive of mode `TRIANGLES` (the default): its `POSITION` accessor transformed to world
//! space and its indices (or, without indices, its vertices in threes) as triangles in order; a
//! mesh used by several nodes is added once per node. The primitive's material is mapped as in
//! `gltf/material.rs`; every material of the file is kept, used or not. The first node (in that
//! order) with a perspective camera gives the scene camera: the node's origin is the eye, its -Z
//! axis the view direction and its +Y axis up; `yfov` is the vertical field of view (its aspect
//! ratio and clip planes are not used: vtq's image size gives the aspect ratio).
//!
//! # What is counted, not used
//! Primitives of other modes (`mode POINTS`, `mode LINES`, `mode TRIANGLE_STRIP`, ...),
//! attributes other than `POSITION` (`attribute NORMAL`, `attribute TEXCOORD_0`, ...) and
//! morph targets, per primitive added; skins (per node), orthographic cameras and cameras after
//! the first; per material its textures, non-opaque alpha modes and base colour alpha;
//! animations, scenes other than the one read, and every extension in `extensionsUsed` except
//! `KHR_materials_emissive_strength`, `KHR_materials_ior` and `KHR_materials_transmission`
//! (which the material mapping reads).
//!
//! # Errors
//! A malformed file is a [`SceneError::Parse`] naming the file, never a panic: a GLB container
//! or JSON that does not parse, a document that the `gltf` crate's validation refuses (an index
//! out of range, a required extension vtq does not read such as mesh compression), a missing or
//! short buffer, an accessor of the wrong type or beyond its data, an index beyond its
//! positions, a node reached twice (glTF nodes form trees), a non-finite material factor, a
//! camera that does not give a valid view, or a file without scenes. A `TRIANGLES` primitive
//! whose vertex count is not a multiple of 3 (which the glTF validator only warns about) loads
//! its whole triangles; the rest is counted as `incomplete triangle`.

mod accessor;
mod buffers;
mod material;

use std::path::Path;

use ::gltf::camera::Projection;
use ::gltf::mesh::Mode;
use ::gltf::Semantic;
use glam::{Mat4, Vec3};

pub use buffers::BufferResolver;

use super::geometry::{read_regular_file, MeshPart, NO_MATERIAL};
use super::text::StatementCounts;
use super::{Camera, SceneError};

/// The extensions vtq reads (in the material mapping); any other in `extensionsUsed` is counted.
const READ_EXTENSIONS: [&str; 3] = [
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
];

/// The validation problems named in an error before the rest are only counted.
const SHOWN_PROBLEMS: usize = 3;

/// What one glTF file adds to a scene.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GltfFile {
    /// The triangles of the scene's meshes in world space, with the file's materials.
    pub part: MeshPart,
    /// The first perspective camera, if the scene has one.
    pub camera: Option<Camera>,
    /// What the file holds but vtq does not use, by kind.
    pub ignored: StatementCounts,
}

/// Read the glTF or GLB file at `path`, its buffer files resolved relative to its folder (see
/// [`parse_gltf`]).
///
/// Errors: [`SceneError::Io`] when the file or a buffer file cannot be read, else as
/// [`parse_gltf`].
pub fn read_gltf_file(path: &Path) -> Result<GltfFile, SceneError> {
    let bytes = read_regular_file(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse_gltf(&bytes, path, &mut |name| {
        let full = dir.join(name);
        if full.exists() {
            read_regular_file(&full).map(Some)
        } else {
            Ok(None)
        }
    })
}

/// Parse a glTF (JSON) or GLB (binary, recognized by its `glTF` magic) file's bytes; `path`
/// names the file in errors and `resolve` gives the bytes of buffer files named by relative
/// URIs. See the module documentation for what is read, counted and refused.
pub fn parse_gltf(
    bytes: &[u8],
    path: &Path,
    resolve: &mut BufferResolver<'_>,
) -> Result<GltfFile, SceneError> {
    let fail = |reason: String| parse_error(path, reason);
    let (gltf, blob) = read_document(bytes).map_err(fail)?;
    let buffers = buffers::load_buffers(&gltf, blob.as_deref(), path, resolve)?;
    let mut file = GltfFile::default();
    let ignored = &mut file.ignored;
    for name in gltf.extensions_used() {
        if !READ_EXTENSIONS.contains(&name) {
            ignored.add(&format!("extension {name}"), 1);
        }
    }
    let animations = gltf.animations().count() as u64;
    if animations > 0 {
        ignored.add("animation", animations);
    }
    for m in gltf.materials() {
        let material = material::material_from_gltf(&m, ignored).map_err(fail)?;
        file.part.materials.push(material);
    }
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or_else(|| fail("the file has no scene: nothing to render".into()))?;
    let other_scenes = gltf.scenes().count() as u64 - 1;
    if other_scenes > 0 {
        ignored.add("scene (not read)", other_scenes);
    }
    let mut visited = vec![false; gltf.nodes().count()];
    // Depth first, in file order: children are pushed last to first.
    let mut stack: Vec<(::gltf::Node<'_>, Mat4)> =
        scene.nodes().map(|node| (node, Mat4::IDENTITY)).collect();
    stack.reverse();
    while let Some((node, parent)) = stack.pop() {
        let n = node.index();
        if std::mem::replace(&mut visited[n], true) {
            return Err(fail(format!(
                "node {n} is reached twice from scene {} (glTF nodes form trees)",
                scene.index()
            )));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if node.skin().is_some() {
            file.ignored.add("skin", 1);
        }
        if let Some(camera) = node.camera() {
            add_camera(&mut file, &camera, world).map_err(|e| fail(format!("node {n}: {e}")))?;
        }
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                add_primitive(&mut file, &primitive, world, &buffers).map_err(|e| {
                    fail(format!(
                        "node {n}, mesh {} primitive {}: {e}",
                        mesh.index(),
                        primitive.index()
                    ))
                })?;
            }
        }
        let first_child = stack.len();
        stack.extend(node.children().map(|child| (child, world)));
        stack[first_child..].reverse();
    }
    Ok(file)
}

/// Make `camera`, placed by `world`, the file's camera if it is the first perspective one;
/// otherwise count it.
fn add_camera(file: &mut GltfFile, camera: &::gltf::Camera<'_>, world: Mat4) -> Result<(), String> {
    let Projection::Perspective(perspective) = camera.projection() else {
        file.ignored.add("camera (orthographic)", 1);
        return Ok(());
    };
    if file.camera.is_some() {
        file.ignored.add("camera (not the first)", 1);
        return Ok(());
    }
    let eye = world.transform_point3(Vec3::ZERO);
    let view = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
    let found = Camera {
        eye,
        look_at: eye + view,
        up: world.transform_vector3(Vec3::Y),
        fov_y_deg: perspective.yfov().to_degrees(),
    };
    found
        .check()
        .map_err(|e| format!("camera {}: {e}", camera.index()))?;
    file.camera = Some(found);
    Ok(())
}

/// Append the triangles of `primitive`, placed by `world`, or count a primitive of another
/// mode; count its attributes other than `POSITION` and its morph targets.
fn add_primitive(
    file: &mut GltfFile,
    primitive: &::gltf::Primitive<'_>,
    world: Mat4,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    let mode = primitive.mode();
    if mode != Mode::Triangles {
        file.ignored.add(&format!("mode {}", mode_name(mode)), 1);
        return Ok(());
    }
    for (semantic, _) in primitive.attributes() {
        if semantic != Semantic::Positions {
            file.ignored
                .add(&format!("attribute {}", semantic.to_string()), 1);
        }
    }
    if primitive.morph_targets().next().is_some() {
        file.ignored.add("morph targets", 1);
    }
    let positions = primitive
        .get(&Semantic::Positions)
        .ok_or("a TRIANGLES primitive without POSITION")?;
    let mut vertices = accessor::read_positions(&positions, buffers)?;
    let indices = match primitive.indices() {
        Some(indices) => accessor::read_indices(&indices, buffers)?,
        None => (0..u32::try_from(vertices.len()).map_err(|_| "too many vertices")?).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        // The glTF validator warns about this but the file stays valid: the last vertices are
        // not a triangle.
        file.ignored.add("incomplete triangle", 1);
    }
    if let Some(&bad) = indices.iter().find(|&&v| v as usize >= vertices.len()) {
        return Err(format!(
            "index {bad} is out of range ({} positions)",
            vertices.len()
        ));
    }
    if world != Mat4::IDENTITY {
        for p in &mut vertices {
            *p = world.transform_point3(*p);
        }
    }
    let part = &mut file.part;
    let base = u32::try_from(part.vertices.len())
        .ok()
        .filter(|b| b.checked_add(vertices.len() as u32).is_some())
        .ok_or("more than 2^32 vertices in one file")?;
    part.nonfinite_vertices += vertices.iter().filter(|p| !p.is_finite()).count() as u64;
    part.vertices.extend(vertices);
    let slot = primitive
        .material()
        .index()
        .map_or(NO_MATERIAL, |m| m as u32);
    for tri in indices.chunks_exact(3) {
        part.triangles
            .push([base + tri[0], base + tri[1], base + tri[2]]);
        part.tri_slot.push(slot);
    }
    Ok(())
}

/// The name glTF gives a primitive mode.
fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

/// The validated document of a glTF or GLB file and the GLB binary chunk, or why not.
///
/// The `gltf` crate panics on three malformed inputs, which are refused here before it could
/// meet them: a GLB header whose total length is shorter than the header (subtracted without a
/// check), a primitive whose `POSITION` names an accessor that does not exist (indexed without
/// a check in the crate's validation), and a camera without the projection its `type` names
/// (which the validation does not check and `Camera::projection` unwraps).
fn read_document(bytes: &[u8]) -> Result<(::gltf::Document, Option<Vec<u8>>), String> {
    let (json, blob) = if bytes.starts_with(b"glTF") {
        check_glb_header(bytes)?;
        let glb = ::gltf::Glb::from_slice(bytes).map_err(describe)?;
        (glb.json, glb.bin.map(|bin| bin.into_owned()))
    } else {
        (std::borrow::Cow::Borrowed(bytes), None)
    };
    let root =
        ::gltf::json::Root::from_slice(&json).map_err(|e| format!("invalid glTF JSON: {e}"))?;
    check_unchecked(&root)?;
    let document = ::gltf::Document::from_json(root).map_err(describe)?;
    Ok((document, blob))
}

/// Refuse what the `gltf` crate's validation lets through but its document model would panic
/// on (see [`read_document`]).
fn check_unchecked(root: &::gltf::json::Root) -> Result<(), String> {
    use ::gltf::json::camera::Type;
    use ::gltf::json::validation::Checked;
    let position = Checked::Valid(Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= root.accessors.len() {
                    return Err(format!(
                        "invalid glTF: meshes[{m}].primitives[{p}].attributes[\"POSITION\"]: \
                         accessor {} does not exist ({} accessors)",
                        index.value(),
                        root.accessors.len()
                    ));
                }
            }
        }
    }
    for (c, camera) in root.cameras.iter().enumerate() {
        let (name, missing) = match camera.type_ {
            Checked::Valid(Type::Perspective) => ("perspective", camera.perspective.is_none()),
            Checked::Valid(Type::Orthographic) => ("orthographic", camera.orthographic.is_none()),
            Checked::Invalid => ("", false),
        };
        if missing {
            return Err(format!(
                "invalid glTF: cameras[{c}]: its type is {name} but it has no \"{name}\" object"
            ));
        }
    }
    Ok(())
}

/// Refuse a GLB whose header gives a total length shorter than the header itself, which the
/// `gltf` crate would subtract without a check.
fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    let length = bytes
        .get(8..12)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .ok_or("invalid GLB: the file ends inside its 12-byte header")?;
    if length < 12 {
        return Err(format!(
            "invalid GLB: its header gives a length of {length} bytes, less than the header"
        ));
    }
    Ok(())
}

/// One line describing why the `gltf` crate refused a file.
fn describe(error: ::gltf::Error) -> String {
    match error {
        ::gltf::Error::Validation(problems) => {
            let shown: Vec<String> = problems
                .iter()
                .take(SHOWN_PROBLEMS)
                .map(|(path, problem)| format!("{path}: {problem}"))
                .collect();
            let more = problems.len().saturating_sub(SHOWN_PROBLEMS);
            format!(
                "invalid glTF: {}{}",
                shown.join("; "),
                if more > 0 {
                    format!("; and {more} more")
                } else {
                    String::new()
                }
            )
        }
        ::gltf::Error::Binary(e) => format!("invalid GLB: {e}"),
        ::gltf::Error::Deserialize(e) => format!("invalid glTF JSON: {e}"),
        other => format!("invalid glTF: {other}"),
    }
}

/// A [`SceneError::Parse`] naming `path`.
fn parse_error(path: &Path, reason: String) -> SceneError {
    SceneError::Parse {
        path: path.display().to_string(),
        reason,
    }
}
