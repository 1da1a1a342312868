//! Wavefront OBJ geometry and MTL materials, loaded with `tobj` after a line-by-line check that
//! gives malformed files an error naming the file and line.
//!
//! Triangle order: faces in file order, polygons as fans `(v0, v1, v2), (v0, v2, v3), ...` (tobj's
//! `triangulate` option, which emits exactly these fans in face order); files appended in the
//! order they are loaded. Vertices are shared: every distinct position (bit-exact) is stored once
//! across all loaded files. Degenerate (zero-area) triangles are kept. Polylines (`l`) and points
//! are not surfaces and are ignored.
//!
//! MTL to [`Material`] mapping, first rule that applies:
//! 1. `Ke` with a component > 0: `Light { emit: Ke }`.
//! 2. `illum` 4, 6, 7 or 9 (transparent models), or `d < 1` together with `Ni`:
//!    `Dielectric { ior: Ni }` (1.5 when `Ni` is absent or not > 0).
//! 3. `Pm >= 0.5` (the PBR "metallic" extension Blender writes): `Metal { albedo: Kd }`.
//! 4. `illum` 3 or 5 (mirror models), or `Ks` non-zero with `Ns >= 900` (a nearly mirror-sharp
//!    highlight): `Metal { albedo: Ks }`.
//! 5. Otherwise `Lambertian { albedo: Kd }`.
//!
//! A missing `Kd` is 0.5 grey (and a missing `Ks` in rule 4 falls back to `Kd`). Metal fuzz is
//! `Pr` (Blender's roughness) when present, else `1 - sqrt(Ns / 1000)` (the inverse of Blender's
//! `Ns = 1000 (1 - roughness)^2`), else 0; clamped to `[0, 1]`. `Ks 0.5` with `illum 2` and no
//! `Ns`, as Blender writes for plain diffuse surfaces, therefore stays Lambertian. Faces without
//! a material, or whose `usemtl` names a material no library defines, use [`Material::DEFAULT`].

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::{Material, SceneError};

/// Triangles, shared vertices and materials accumulated from OBJ files into one world space.
#[derive(Debug, Clone)]
pub struct ObjGeometry {
    /// Shared vertex positions: each distinct position once, only positions some face uses.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`, in load order.
    pub triangles: Vec<[u32; 3]>,
    /// Material index (into `materials`) of each triangle.
    pub tri_material: Vec<u32>,
    /// Distinct materials; index 0 is [`Material::DEFAULT`].
    pub materials: Vec<Material>,
    /// Material libraries named by `mtllib` that do not exist, in the order met (their faces use
    /// the default material). Loading does not print; the caller decides how to warn.
    pub missing_mtl: Vec<PathBuf>,
    /// Position bit patterns to vertex ids, for sharing.
    vertex_ids: HashMap<[u32; 3], u32>,
}

impl Default for ObjGeometry {
    fn default() -> Self {
        ObjGeometry::new()
    }
}

impl ObjGeometry {
    /// Empty geometry with only the default material.
    pub fn new() -> Self {
        ObjGeometry {
            positions: Vec::new(),
            triangles: Vec::new(),
            tri_material: Vec::new(),
            materials: vec![Material::DEFAULT],
            missing_mtl: Vec::new(),
            vertex_ids: HashMap::new(),
        }
    }

    /// Append the OBJ file at `path` (its `mtllib`s are resolved relative to its folder) and
    /// return the number of triangles it added. On error nothing is appended.
    ///
    /// Errors: [`SceneError::Io`] when the file (or an existing material library) cannot be
    /// read; [`SceneError::Parse`] naming the file and line for a malformed line: a face with
    /// fewer than 3 vertices, an index that is 0 or out of range, a token that is not a number,
    /// a non-finite vertex coordinate, a malformed `.mtl` line.
    pub fn load_file(&mut self, path: &Path) -> Result<usize, SceneError> {
        let bytes = std::fs::read(path).map_err(|e| io_error(path, &e))?;
        self.load_str(&String::from_utf8_lossy(&bytes), path)
    }

    /// Append OBJ text as if read from `path` (used in errors and to resolve `mtllib`s) and
    /// return the number of triangles it added. On error nothing is appended.
    pub fn load_str(&mut self, text: &str, path: &Path) -> Result<usize, SceneError> {
        let has_polylines = check_obj_text(text, path)?;
        // Polylines are not surfaces; tobj would turn an `l` with 3+ vertices into a face.
        let filtered;
        let surfaces = if has_polylines {
            filtered = text
                .lines()
                .filter(|l| l.split_whitespace().next() != Some("l"))
                .collect::<Vec<_>>()
                .join("\n");
            filtered.as_str()
        } else {
            text
        };

        let dir = path.parent().unwrap_or(Path::new("."));
        let missing = RefCell::new(Vec::new());
        let failure = RefCell::new(None);
        let options = tobj::LoadOptions {
            single_index: false,
            triangulate: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let (models, file_materials) =
            tobj::load_obj_buf(&mut surfaces.as_bytes(), &options, |lib| {
                load_mtl(&dir.join(lib), &missing, &failure)
            })
            .map_err(|e| parse_error(path, format!("malformed OBJ: {e}")))?;
        if let Some(err) = failure.into_inner() {
            return Err(err);
        }
        // With every library missing tobj reports an error here; faces then use the default.
        let file_materials = file_materials.unwrap_or_default();

        let mark = (
            self.positions.len(),
            self.triangles.len(),
            self.materials.len(),
        );
        match self.append(&models, &file_materials, path) {
            Ok(()) => {
                self.missing_mtl.extend(missing.into_inner());
                Ok(self.triangles.len() - mark.1)
            }
            Err(err) => {
                for p in self.positions.drain(mark.0..) {
                    self.vertex_ids
                        .remove(&[p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]);
                }
                self.triangles.truncate(mark.1);
                self.tri_material.truncate(mark.1);
                self.materials.truncate(mark.2);
                Err(err)
            }
        }
    }

    /// Append tobj's models (in order) and the materials they use.
    fn append(
        &mut self,
        models: &[tobj::Model],
        file_materials: &[tobj::Material],
        path: &Path,
    ) -> Result<(), SceneError> {
        let material_ids: Vec<u32> = file_materials
            .iter()
            .map(|m| self.intern_material(material_from_mtl(m)))
            .collect();
        for model in models {
            let mesh = &model.mesh;
            let material = mesh
                .material_id
                .and_then(|id| material_ids.get(id).copied())
                .unwrap_or(0);
            let mut local_ids = Vec::with_capacity(mesh.positions.len() / 3);
            for p in mesh.positions.chunks_exact(3) {
                local_ids.push(self.vertex_id(Vec3::new(p[0], p[1], p[2]), path)?);
            }
            for tri in mesh.indices.chunks_exact(3) {
                let corner = |k: usize| {
                    local_ids.get(tri[k] as usize).copied().ok_or_else(|| {
                        parse_error(path, "tobj produced a face index out of range".into())
                    })
                };
                self.triangles.push([corner(0)?, corner(1)?, corner(2)?]);
                self.tri_material.push(material);
            }
        }
        Ok(())
    }

    /// The id of `p`, adding it if it is new.
    fn vertex_id(&mut self, p: Vec3, path: &Path) -> Result<u32, SceneError> {
        let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        if let Some(&id) = self.vertex_ids.get(&key) {
            return Ok(id);
        }
        let id = u32::try_from(self.positions.len())
            .map_err(|_| parse_error(path, "more than 2^32 distinct vertices".into()))?;
        self.positions.push(p);
        self.vertex_ids.insert(key, id);
        Ok(id)
    }

    /// The index of `m` in `materials`, adding it if it is new.
    fn intern_material(&mut self, m: Material) -> u32 {
        let id = match self.materials.iter().position(|&x| x == m) {
            Some(i) => i,
            None => {
                self.materials.push(m);
                self.materials.len() - 1
            }
        };
        id as u32
    }
}

/// The [`Material`] of an MTL material, by the mapping in this module's documentation. `Pm` and
/// `Pr` are read from tobj's unknown parameters; a value there that is not a number counts as
/// absent (files loaded through [`ObjGeometry`] have already been checked).
pub fn material_from_mtl(m: &tobj::Material) -> Material {
    let extra = |key: &str| {
        m.unknown_param
            .get(key)
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse::<f32>().ok())
    };
    let kd = m.diffuse.map(Vec3::from).unwrap_or(Vec3::splat(0.5));
    let ks = m.specular.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let ke = m.emissive.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let illum = m.illumination_model;
    let fuzz = || {
        let f = match (extra("Pr"), m.shininess) {
            (Some(roughness), _) => roughness,
            (None, Some(ns)) => 1.0 - (ns.clamp(0.0, 1000.0) / 1000.0).sqrt(),
            (None, None) => 0.0,
        };
        f.clamp(0.0, 1.0)
    };

    if ke.max_element() > 0.0 {
        return Material::Light { emit: ke };
    }
    let transparent_model = matches!(illum, Some(4 | 6 | 7 | 9));
    let see_through = m.dissolve.is_some_and(|d| d < 1.0) && m.optical_density.is_some();
    if transparent_model || see_through {
        let ior = m.optical_density.filter(|&n| n > 0.0).unwrap_or(1.5);
        return Material::Dielectric { ior };
    }
    if extra("Pm").is_some_and(|pm| pm >= 0.5) {
        return Material::Metal {
            albedo: kd,
            fuzz: fuzz(),
        };
    }
    let sharp_highlight = ks != Vec3::ZERO && m.shininess.is_some_and(|ns| ns >= 900.0);
    if matches!(illum, Some(3 | 5)) || sharp_highlight {
        let albedo = if ks != Vec3::ZERO { ks } else { kd };
        return Material::Metal {
            albedo,
            fuzz: fuzz(),
        };
    }
    Material::Lambertian { albedo: kd }
}

/// tobj's material loader: read and check the library at `full`, recording a missing file in
/// `missing` and any other failure in `failure` (tobj only sees an opaque error).
fn load_mtl(
    full: &Path,
    missing: &RefCell<Vec<PathBuf>>,
    failure: &RefCell<Option<SceneError>>,
) -> tobj::MTLLoadResult {
    let fail = |err: SceneError| {
        failure.borrow_mut().get_or_insert(err);
        Err(tobj::LoadError::OpenFileFailed)
    };
    let bytes = match std::fs::read(full) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            missing.borrow_mut().push(full.to_path_buf());
            return Err(tobj::LoadError::OpenFileFailed);
        }
        Err(e) => return fail(io_error(full, &e)),
    };
    let text = String::from_utf8_lossy(&bytes);
    if let Err(err) = check_mtl_text(&text, full) {
        return fail(err);
    }
    match tobj::load_mtl_buf(&mut text.as_bytes()) {
        Ok(result) => Ok(result),
        Err(e) => fail(parse_error(
            full,
            format!("malformed material library: {e}"),
        )),
    }
}

/// Check every line of OBJ text that tobj interprets, so that tobj cannot fail (or panic) on it
/// and errors carry a line number. Returns whether the text has polylines (`l`).
fn check_obj_text(text: &str, path: &Path) -> Result<bool, SceneError> {
    let (mut n_v, mut n_vt, mut n_vn) = (0usize, 0usize, 0usize);
    let mut colored: Option<bool> = None;
    let mut has_polylines = false;
    for (i, line) in text.lines().enumerate() {
        let at_line = |reason: String| parse_error(path, format!("line {}: {reason}", i + 1));
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let values = words
                    .map(|w| number(w, "vertex coordinate"))
                    .collect::<Result<Vec<f32>, String>>()
                    .map_err(at_line)?;
                let mut p = match values.len() {
                    3 | 4 | 6 => Vec3::new(values[0], values[1], values[2]),
                    n => {
                        return Err(at_line(format!(
                            "vertex needs x y z [w | r g b], found {n} values"
                        )))
                    }
                };
                if values.len() == 4 {
                    if values[3] == 0.0 {
                        return Err(at_line("vertex has w = 0".into()));
                    }
                    p /= values[3];
                }
                if !p.is_finite() {
                    return Err(at_line(format!("non-finite vertex coordinate {p}")));
                }
                let has_color = values.len() == 6;
                if *colored.get_or_insert(has_color) != has_color {
                    return Err(at_line(
                        "vertices with and without colours are mixed".into(),
                    ));
                }
                n_v += 1;
            }
            "vt" | "vn" => {
                let need = if keyword == "vt" { 2 } else { 3 };
                let values = words
                    .take(need)
                    .map(|w| number(w, "coordinate"))
                    .collect::<Result<Vec<f32>, String>>()
                    .map_err(at_line)?;
                if values.len() < need {
                    return Err(at_line(format!("{keyword} needs {need} numbers")));
                }
                if keyword == "vt" {
                    n_vt += 1;
                } else {
                    n_vn += 1;
                }
            }
            "f" | "l" => {
                let mut corners = 0;
                for word in words {
                    check_corner(word, [n_v, n_vt, n_vn]).map_err(&at_line)?;
                    corners += 1;
                }
                if keyword == "l" {
                    has_polylines = true;
                } else if corners < 3 {
                    return Err(at_line(format!(
                        "face needs at least 3 vertices, found {corners}"
                    )));
                }
            }
            "usemtl" | "mtllib" => {
                // tobj takes the rest of the line after the first space as the name.
                let name = line.split_once(' ').map_or("", |(_, rest)| rest.trim());
                if name.is_empty() {
                    return Err(at_line(format!("{keyword} needs a name")));
                }
            }
            _ => {}
        }
    }
    Ok(has_polylines)
}

/// Check one face corner `v`, `v/vt`, `v//vn` or `v/vt/vn` against the element counts so far.
fn check_corner(word: &str, counts: [usize; 3]) -> Result<(), String> {
    const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let parts: Vec<&str> = word.split('/').collect();
    if parts.len() > 3 || parts[0].is_empty() {
        return Err(format!(
            "'{word}' is not a face vertex (v, v/vt, v//vn or v/vt/vn)"
        ));
    }
    for ((part, count), kind) in parts.iter().zip(counts).zip(KINDS) {
        if part.is_empty() {
            continue;
        }
        let index: i64 = part
            .parse()
            .map_err(|_| format!("'{part}' in '{word}' is not a {kind} index"))?;
        if index == 0 || index.unsigned_abs() > count as u64 {
            return Err(format!(
                "{kind} index {index} is out of range ({count} defined so far; OBJ indices \
                 start at 1, negative ones count back)"
            ));
        }
    }
    Ok(())
}

/// Check every line of MTL text that tobj interprets or that the material mapping reads.
fn check_mtl_text(text: &str, path: &Path) -> Result<(), SceneError> {
    for (i, line) in text.lines().enumerate() {
        let at_line = |reason: String| parse_error(path, format!("line {}: {reason}", i + 1));
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let need = match keyword {
            "Ka" | "Kd" | "Ks" | "Ke" => 3,
            "Ns" | "Ni" | "d" | "Pm" | "Pr" => 1,
            "illum" => {
                let model = words.next().unwrap_or("");
                if model.parse::<u8>().is_err() {
                    return Err(at_line(format!(
                        "illum needs an illumination model number, found '{model}'"
                    )));
                }
                continue;
            }
            "newmtl" | "map_Ka" | "map_Kd" | "map_Ks" | "map_Bump" | "map_bump" | "map_Ns"
            | "map_ns" | "map_NS" | "bump" | "map_d" => {
                if words.next().is_none() {
                    return Err(at_line(format!("{keyword} needs a name")));
                }
                continue;
            }
            _ => continue,
        };
        let values = words
            .take(need)
            .map(|w| number(w, keyword))
            .collect::<Result<Vec<f32>, String>>()
            .map_err(at_line)?;
        if values.len() < need {
            return Err(at_line(format!("{keyword} needs {need} number(s)")));
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(at_line(format!("{keyword} has a non-finite value")));
        }
    }
    Ok(())
}

/// Parse an `f32` token, naming `what` on failure.
fn number(word: &str, what: &str) -> Result<f32, String> {
    word.parse()
        .map_err(|_| format!("'{word}' is not a number ({what})"))
}

/// A [`SceneError::Parse`] for `path`.
fn parse_error(path: &Path, reason: String) -> SceneError {
    SceneError::Parse {
        path: path.display().to_string(),
        reason,
    }
}

/// A [`SceneError::Io`] for `path`.
fn io_error(path: &Path, e: &std::io::Error) -> SceneError {
    SceneError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}
