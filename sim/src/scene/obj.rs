//! Wavefront OBJ geometry: a line reader tolerant of what real exporters write, and the
//! accumulation of files into one world space with shared vertices.
//!
//! # What is read
//! The text as [`super::text::logical_lines`] gives it: UTF-8 with or without a byte-order mark
//! (UTF-16 is refused with an error), LF or CRLF line ends, `\` line continuations. A first word
//! starting with `#` makes a comment. vtq uses these statements:
//! - `v x y z`, `v x y z w` (the position is divided by `w`) and `v x y z r g b` (the colour is
//!   not used: such vertices are counted as `v rgb`);
//! - `f` with 3 or more corners `v`, `v/vt`, `v//vn` or `v/vt/vn`; indices start at 1, negative
//!   ones count back from the last element defined (`-1` is the latest);
//! - `usemtl name` (the rest of the line; empty selects the default material) and
//!   `mtllib file` (the rest of the line, relative to the OBJ file's folder; if no such file
//!   exists and the name has blanks, each word is tried as a file of its own; a missing library
//!   is not an error, see [`ObjGeometry::missing_mtl`]).
//!
//! Every other statement (`vt`, `vn`, `o`, `g`, `s`, `l`, `p`, `vp`, `curv`, `mg`, ... and an
//! `mtllib` without a name) is not used by vtq: it is skipped without reading its arguments and
//! counted by keyword ([`ObjFile::ignored`]), so that the load summary names everything that was
//! dropped. Broken data is an error naming the file and line: a first word that is not a keyword
//! (letters, digits and `_`, starting with a letter), a vertex whose numbers are not numbers or
//! are not 3, 4 or 6, a face with fewer than 3 corners, an index that is 0, not an integer, or
//! out of range (counting only elements defined before the face). A vertex that parses to a
//! non-finite position (`nan`, `inf`, `1e39`, `w = 0`) is not an error: it is counted, and every
//! triangle using it is left out and counted ([`ObjGeometry::nonfinite_triangles`]).
//!
//! # Triangles and vertices
//! Faces in file order, polygons as fans `(v0, v1, v2), (v0, v2, v3), ...`; files appended in
//! the order they are loaded. Vertices are shared: every distinct position (bit-exact) is stored
//! once across all loaded files, in the order faces first use them; vertices no kept triangle
//! uses are not stored. Degenerate (zero-area) triangles are kept (the BVH build leaves them out
//! and counts them). A face's material is the one its last `usemtl` selected among the
//! materials of the libraries loaded before that `usemtl` (a later library's material wins over
//! an earlier one of the same name); faces before any `usemtl`, after an empty one, or whose
//! `usemtl` names a material no library defines ([`ObjGeometry::undefined_materials`]) use
//! [`Material::DEFAULT`]. Materials are mapped as in [`super::mtl`]; every material of every
//! library is kept (distinct values once), used or not.
//!
//! # Why not `tobj`
//! vtq used `tobj` until it met real exporters' files: tobj does not strip a byte-order mark (so
//! the first `v` of such a file was silently skipped and every later index shifted), rejects an
//! empty `usemtl` (which Blender writes for faces without a material), does not join `\`
//! continuations, skips unknown statements without telling, and has no line numbers in its
//! errors (vtq had to check every line in a first pass of its own). A single-pass reader of the
//! few statements vtq uses does all of that, and loads the shared scenes faster; its result is
//! bit-identical to what the tobj-based loader built.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;

use super::mtl::{material_from_mtl, parse_mtl, preview, MtlLibrary, MtlMaterial};
use super::text::{decode, is_keyword, logical_lines, StatementCounts};
use super::{Material, SceneError};

/// The material slot of a triangle without a material.
const NO_MATERIAL: u32 = u32::MAX;

/// One OBJ file, parsed but not yet added to an [`ObjGeometry`].
#[derive(Debug, Clone, Default)]
pub struct ObjFile {
    /// Every `v` position in file order (OBJ index - 1), possibly non-finite.
    pub vertices: Vec<Vec3>,
    /// Triangles (polygons as fans) as indices into `vertices`, in file order.
    pub triangles: Vec<[u32; 3]>,
    /// Material slot of each triangle: an index into `materials`, or `u32::MAX` for the default.
    pub tri_slot: Vec<u32>,
    /// The materials of the libraries loaded by `mtllib`, in load order.
    pub materials: Vec<MtlMaterial>,
    /// Statements read but not used, by keyword.
    pub ignored: StatementCounts,
    /// Number of `v` statements whose position is not finite.
    pub nonfinite_vertices: u64,
    /// Library names (as written after `mtllib`) that the resolver did not find, once each.
    pub missing_mtl: Vec<String>,
    /// Distinct names that `usemtl` selected but no loaded library defined, in order met.
    pub undefined_materials: Vec<String>,
}

/// Resolves an `mtllib` name to its parsed library (`Ok(None)` when no such file exists).
pub type LibraryResolver<'a> = dyn FnMut(&str) -> Result<Option<Arc<MtlLibrary>>, SceneError> + 'a;

/// Parse OBJ text; `path` names the file in errors and `resolve` loads `mtllib` libraries.
///
/// Errors: [`SceneError::Parse`] naming the file and line for broken data (see the module
/// documentation), and whatever `resolve` returns.
pub fn parse_obj(
    text: &str,
    path: &Path,
    resolve: &mut LibraryResolver<'_>,
) -> Result<ObjFile, SceneError> {
    let mut file = ObjFile::default();
    let (mut n_vt, mut n_vn) = (0usize, 0usize);
    let mut slot = NO_MATERIAL;
    let mut slots_by_name: HashMap<String, u32> = HashMap::new();
    let mut undefined: HashSet<String> = HashSet::new();
    let mut missing_seen: HashSet<String> = HashSet::new();
    let mut corners: Vec<u32> = Vec::new();
    for (number, line) in logical_lines(text) {
        let at_line = |reason: String| SceneError::Parse {
            path: path.display().to_string(),
            reason: format!("line {number}: {reason}"),
        };
        let line = line.trim();
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        if keyword.starts_with('#') {
            continue;
        }
        // Arguments end at a word starting with `#` (a trailing comment).
        let args = words.take_while(|w| !w.starts_with('#'));
        match keyword {
            "v" => {
                let mut values = [0.0f32; 7];
                let mut n = 0;
                for word in args {
                    if n == values.len() {
                        n += 1;
                        break;
                    }
                    values[n] = word.parse().map_err(|_| {
                        at_line(format!(
                            "'{}' is not a number (vertex coordinate)",
                            preview(word)
                        ))
                    })?;
                    n += 1;
                }
                let mut p = Vec3::new(values[0], values[1], values[2]);
                match n {
                    3 => {}
                    4 => p /= values[3],
                    6 => file.ignored.add("v rgb", 1),
                    _ => {
                        return Err(at_line(format!(
                            "a vertex needs x y z, x y z w or x y z r g b; found {} numbers",
                            if n > values.len() {
                                format!("more than {}", values.len())
                            } else {
                                n.to_string()
                            }
                        )))
                    }
                }
                if !p.is_finite() {
                    file.nonfinite_vertices += 1;
                }
                if file.vertices.len() == u32::MAX as usize {
                    return Err(at_line("more than 2^32 - 1 vertices in one file".into()));
                }
                file.vertices.push(p);
            }
            "f" => {
                corners.clear();
                for word in args {
                    let v = corner(word, [file.vertices.len(), n_vt, n_vn]).map_err(&at_line)?;
                    corners.push(v);
                }
                if corners.len() < 3 {
                    return Err(at_line(format!(
                        "a face needs at least 3 vertices, found {}",
                        corners.len()
                    )));
                }
                for pair in corners[1..].windows(2) {
                    file.triangles.push([corners[0], pair[0], pair[1]]);
                    file.tri_slot.push(slot);
                }
            }
            "usemtl" => {
                let name = line[keyword.len()..].trim();
                slot = if name.is_empty() {
                    NO_MATERIAL
                } else if let Some(&s) = slots_by_name.get(name) {
                    s
                } else {
                    if undefined.insert(name.to_string()) {
                        file.undefined_materials.push(name.to_string());
                    }
                    NO_MATERIAL
                };
            }
            "mtllib" => {
                let name = line[keyword.len()..].trim();
                if name.is_empty() {
                    file.ignored.add("mtllib (no name)", 1);
                    continue;
                }
                let mut libraries = Vec::new();
                match resolve(name)? {
                    Some(library) => libraries.push(library),
                    None => {
                        let mut missing = Vec::new();
                        if name.contains(char::is_whitespace) {
                            for part in name.split_whitespace() {
                                match resolve(part)? {
                                    Some(library) => libraries.push(library),
                                    None => missing.push(part),
                                }
                            }
                        }
                        if libraries.is_empty() {
                            missing = vec![name];
                        }
                        for name in missing {
                            if missing_seen.insert(name.to_string()) {
                                file.missing_mtl.push(name.to_string());
                            }
                        }
                    }
                }
                for library in libraries {
                    for m in &library.materials {
                        let s = u32::try_from(file.materials.len())
                            .ok()
                            .filter(|&s| s != NO_MATERIAL)
                            .ok_or_else(|| at_line("too many materials".into()))?;
                        slots_by_name.insert(m.name.clone(), s);
                        file.materials.push(m.clone());
                    }
                }
            }
            _ if is_keyword(keyword) => {
                match keyword {
                    "vt" => n_vt += 1,
                    "vn" => n_vn += 1,
                    _ => {}
                }
                file.ignored.add(keyword, 1);
            }
            _ => {
                return Err(at_line(format!(
                    "'{}' is not an OBJ statement",
                    preview(keyword)
                )))
            }
        }
    }
    Ok(file)
}

/// The 0-based vertex index of a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`, checking each
/// index against the number of vertices, texture coordinates and normals defined so far.
fn corner(word: &str, counts: [usize; 3]) -> Result<u32, String> {
    const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let mut parts = word.split('/');
    let mut vertex = 0;
    for (k, (count, kind)) in counts.into_iter().zip(KINDS).enumerate() {
        let part = parts.next().unwrap_or("");
        if part.is_empty() && k > 0 {
            continue;
        }
        let index: i64 = part.parse().map_err(|_| {
            if k == 0 && part.is_empty() {
                format!(
                    "'{}' is not a face vertex (v, v/vt, v//vn or v/vt/vn)",
                    preview(word)
                )
            } else {
                format!(
                    "'{}' in '{}' is not a {kind} index",
                    preview(part),
                    preview(word)
                )
            }
        })?;
        let resolved = if index > 0 {
            index - 1
        } else {
            count as i64 + index
        };
        if index == 0 || resolved < 0 || resolved >= count as i64 {
            return Err(format!(
                "{kind} index {index} is out of range ({count} defined so far; OBJ indices \
                 start at 1, negative ones count back)"
            ));
        }
        if k == 0 {
            vertex = resolved as u32;
        }
    }
    if parts.next().is_some() {
        return Err(format!(
            "'{}' is not a face vertex (v, v/vt, v//vn or v/vt/vn)",
            preview(word)
        ));
    }
    Ok(vertex)
}

/// Triangles, shared vertices and materials accumulated from OBJ files into one world space,
/// with the counts of what was read but not used or left out.
#[derive(Debug, Clone)]
pub struct ObjGeometry {
    /// Shared vertex positions: each distinct position once, only positions a triangle uses.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`, in load order.
    pub triangles: Vec<[u32; 3]>,
    /// Material index (into `materials`) of each triangle.
    pub tri_material: Vec<u32>,
    /// Distinct materials; index 0 is [`Material::DEFAULT`].
    pub materials: Vec<Material>,
    /// Material libraries named by `mtllib` that do not exist, once each, in the order met
    /// (their faces use the default material). Loading does not print; the caller decides how
    /// to warn.
    pub missing_mtl: Vec<PathBuf>,
    /// Names that `usemtl` selected but no loaded library defined, once each, in order met.
    pub undefined_materials: Vec<String>,
    /// OBJ statements read but not used, by keyword.
    pub ignored: StatementCounts,
    /// MTL statements read but not used, by keyword (each library file counted once).
    pub mtl_ignored: StatementCounts,
    /// Vertices whose position is not finite.
    pub nonfinite_vertices: u64,
    /// Triangles left out because a corner's position is not finite.
    pub nonfinite_triangles: u64,
    /// Position bit patterns to vertex ids, for sharing.
    vertex_ids: HashMap<[u32; 3], u32>,
    /// Material values (see [`material_key`]) to their index in `materials`.
    material_ids: HashMap<[u32; 5], u32>,
    /// The entries of `missing_mtl` and `undefined_materials`, for finding them fast.
    reported: (HashSet<PathBuf>, HashSet<String>),
    /// Libraries read so far by path (`None`: no such file).
    libraries: HashMap<PathBuf, Option<Arc<MtlLibrary>>>,
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
            undefined_materials: Vec::new(),
            ignored: StatementCounts::default(),
            mtl_ignored: StatementCounts::default(),
            nonfinite_vertices: 0,
            nonfinite_triangles: 0,
            vertex_ids: HashMap::new(),
            material_ids: HashMap::from([(material_key(&Material::DEFAULT), 0)]),
            reported: (HashSet::new(), HashSet::new()),
            libraries: HashMap::new(),
        }
    }

    /// Append the OBJ file at `path` (its `mtllib`s are resolved relative to its folder) and
    /// return the number of triangles it added. On error nothing is appended.
    ///
    /// Errors: [`SceneError::Io`] when the file (or an existing material library) cannot be
    /// read or is not a regular file; [`SceneError::Parse`] naming the file and line for broken
    /// OBJ or MTL data (see the module documentation and [`super::mtl`]).
    pub fn load_file(&mut self, path: &Path) -> Result<usize, SceneError> {
        let bytes = read_regular_file(path)?;
        self.load_str(&decode(&bytes, path)?, path)
    }

    /// Append OBJ text as if read from `path` (used in errors and to resolve `mtllib`s) and
    /// return the number of triangles it added. On error nothing is appended.
    pub fn load_str(&mut self, text: &str, path: &Path) -> Result<usize, SceneError> {
        let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let file = parse_obj(text, path, &mut |name| self.library(dir.join(name)))?;
        self.add(file, &dir)
    }

    /// The library at `full`, read and parsed on first use (`None` when no such file exists).
    fn library(&mut self, full: PathBuf) -> Result<Option<Arc<MtlLibrary>>, SceneError> {
        if let Some(known) = self.libraries.get(&full) {
            return Ok(known.clone());
        }
        let library = match read_regular_file(&full) {
            Ok(bytes) => {
                let library = parse_mtl(&decode(&bytes, &full)?, &full)?;
                self.mtl_ignored.merge(&library.ignored);
                Some(Arc::new(library))
            }
            Err(SceneError::Io { .. }) if !full.exists() => None,
            Err(err) => return Err(err),
        };
        self.libraries.insert(full, library.clone());
        Ok(library)
    }

    /// Append a parsed file (its missing libraries named relative to `dir`) and return the
    /// number of triangles it added. Triangles with a non-finite corner are left out and
    /// counted. On error (more than 2^32 - 1 distinct vertices) nothing is appended.
    pub fn add(&mut self, file: ObjFile, dir: &Path) -> Result<usize, SceneError> {
        let mark = (
            self.positions.len(),
            self.triangles.len(),
            self.materials.len(),
        );
        match self.add_geometry(&file) {
            Ok(left_out) => {
                self.nonfinite_triangles += left_out;
                self.nonfinite_vertices += file.nonfinite_vertices;
                self.ignored.merge(&file.ignored);
                for name in file.missing_mtl {
                    let path = dir.join(name);
                    if self.reported.0.insert(path.clone()) {
                        self.missing_mtl.push(path);
                    }
                }
                for name in file.undefined_materials {
                    if self.reported.1.insert(name.clone()) {
                        self.undefined_materials.push(name);
                    }
                }
                Ok(self.triangles.len() - mark.1)
            }
            Err(err) => {
                for p in self.positions.drain(mark.0..) {
                    self.vertex_ids
                        .remove(&[p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]);
                }
                self.triangles.truncate(mark.1);
                self.tri_material.truncate(mark.1);
                for m in self.materials.drain(mark.2..) {
                    self.material_ids.remove(&material_key(&m));
                }
                Err(err)
            }
        }
    }

    /// Append the materials and the finite triangles of `file`; returns how many triangles
    /// were left out for a non-finite corner.
    fn add_geometry(&mut self, file: &ObjFile) -> Result<u64, SceneError> {
        let material_ids: Vec<u32> = file
            .materials
            .iter()
            .map(|m| self.intern_material(material_from_mtl(m)))
            .collect();
        let mut left_out = 0;
        self.triangles.reserve(file.triangles.len());
        self.tri_material.reserve(file.triangles.len());
        for (tri, &slot) in file.triangles.iter().zip(&file.tri_slot) {
            let corners = tri.map(|v| file.vertices[v as usize]);
            if !corners.iter().all(|p| p.is_finite()) {
                left_out += 1;
                continue;
            }
            let ids = [
                self.vertex_id(corners[0])?,
                self.vertex_id(corners[1])?,
                self.vertex_id(corners[2])?,
            ];
            self.triangles.push(ids);
            self.tri_material
                .push(material_ids.get(slot as usize).copied().unwrap_or(0));
        }
        Ok(left_out)
    }

    /// The id of `p`, adding it if it is new.
    fn vertex_id(&mut self, p: Vec3) -> Result<u32, SceneError> {
        let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        if let Some(&id) = self.vertex_ids.get(&key) {
            return Ok(id);
        }
        let id = u32::try_from(self.positions.len()).map_err(|_| SceneError::Parse {
            path: "scene".into(),
            reason: "more than 2^32 distinct vertices".into(),
        })?;
        self.positions.push(p);
        self.vertex_ids.insert(key, id);
        Ok(id)
    }

    /// The index of `m` in `materials`, adding it if it is new.
    fn intern_material(&mut self, m: Material) -> u32 {
        let next = self.materials.len() as u32;
        let id = *self.material_ids.entry(material_key(&m)).or_insert(next);
        if id == next {
            self.materials.push(m);
        }
        id
    }
}

/// A material's kind and parameters as bits, equal exactly when the materials compare equal
/// (`-0` counts as `0`; parameters are finite).
fn material_key(m: &Material) -> [u32; 5] {
    let bits = |x: f32| (x + 0.0).to_bits();
    match *m {
        Material::Lambertian { albedo } => [0, bits(albedo.x), bits(albedo.y), bits(albedo.z), 0],
        Material::Metal { albedo, fuzz } => [
            1,
            bits(albedo.x),
            bits(albedo.y),
            bits(albedo.z),
            bits(fuzz),
        ],
        Material::Dielectric { ior } => [2, bits(ior), 0, 0, 0],
        Material::Light { emit } => [3, bits(emit.x), bits(emit.y), bits(emit.z), 0],
    }
}

/// The bytes of the regular file at `path` ([`SceneError::Io`] if it cannot be read or is not a
/// regular file: a device or pipe would never end).
fn read_regular_file(path: &Path) -> Result<Vec<u8>, SceneError> {
    let io = |reason: String| SceneError::Io {
        path: path.display().to_string(),
        reason,
    };
    let meta = std::fs::metadata(path).map_err(|e| io(e.to_string()))?;
    if !meta.is_file() {
        return Err(io("not a regular file".into()));
    }
    std::fs::read(path).map_err(|e| io(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<ObjFile, String> {
        parse_obj(text, Path::new("t.obj"), &mut |_| Ok(None)).map_err(|e| e.to_string())
    }

    #[test]
    fn corners_resolve_absolute_and_relative_indices() {
        assert_eq!(corner("2", [3, 0, 0]), Ok(1));
        assert_eq!(corner("-1", [3, 0, 0]), Ok(2));
        assert_eq!(corner("-3/-1/1", [3, 1, 1]), Ok(0));
        assert_eq!(corner("3//2", [3, 0, 2]), Ok(2));
        assert_eq!(corner("1/", [3, 0, 0]), Ok(0));
        for (bad, needle) in [
            ("0", "vertex index 0 is out of range"),
            ("-4", "vertex index -4 is out of range (3 defined"),
            ("4", "vertex index 4"),
            ("1/2", "texture coordinate index 2"),
            ("1//x", "'x' in '1//x' is not a normal index"),
            ("1/1/1/1", "not a face vertex"),
            ("/1", "not a face vertex"),
            ("99999999999999999999", "is not a vertex index"),
        ] {
            let err = corner(bad, [3, 1, 1]).unwrap_err();
            assert!(err.contains(needle), "{bad}: {err}");
        }
    }

    #[test]
    fn trailing_comments_end_the_arguments() {
        let file = parse("v 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nf 1 2 3 # one\n").unwrap();
        assert_eq!(file.vertices.len(), 3);
        assert_eq!(file.triangles, [[0, 1, 2]]);
    }

    #[test]
    fn vertices_need_three_four_or_six_numbers() {
        for n in [0, 1, 2, 5, 7, 8] {
            let numbers = vec!["1"; n].join(" ");
            let err = parse(&format!("v {numbers}\n")).unwrap_err();
            assert!(err.contains("t.obj") && err.contains("line 1"), "{err}");
        }
        let file = parse("v 2 4 6 2\nv 1 1 1 0.5 0.5 0.5\nv 1 1 1 0\n").unwrap();
        assert_eq!(file.vertices[0], Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(file.ignored.get("v rgb"), 1);
        assert_eq!(file.nonfinite_vertices, 1, "w = 0 is a point at infinity");
    }
}
