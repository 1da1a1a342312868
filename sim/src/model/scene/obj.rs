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
//!   is not an error, see [`SceneGeometry::missing_mtl`]).
//!
//! Every other statement (`vt`, `vn`, `o`, `g`, `s`, `l`, `p`, `vp`, `curv`, `mg`, ... and an
//! `mtllib` without a name) is not used by vtq: it is skipped without reading its arguments and
//! counted by keyword ([`ObjFile::ignored`]), so that the load summary names everything that was
//! dropped. Broken data is an error naming the file and line: a first word that is not a keyword
//! (letters, digits and `_`, starting with a letter), a vertex whose numbers are not numbers or
//! are not 3, 4 or 6, a face with fewer than 3 corners, an index that is 0, not an integer, or
//! out of range (counting only elements defined before the face). A vertex that parses to a
//! non-finite position (`nan`, `inf`, `1e39`, `w = 0`) is not an error: it is counted, and every
//! triangle using it is left out and counted ([`SceneGeometry::nonfinite_triangles`]).
//!
//! # Triangles and vertices
//! Faces in file order, polygons as fans `(v0, v1, v2), (v0, v2, v3), ...`; files appended in
//! the order they are loaded. Vertices are shared: every distinct position (bit-exact) is stored
//! once across all loaded files, in the order faces first use them; vertices no kept triangle
//! uses are not stored. Degenerate (zero-area) triangles are kept (the BVH build leaves them out
//! and counts them). A face's material is the one its last `usemtl` selected among the
//! materials of the libraries loaded before that `usemtl` (a later library's material wins over
//! an earlier one of the same name); faces before any `usemtl`, after an empty one, or whose
//! `usemtl` names a material no library defines ([`SceneGeometry::undefined_materials`]) use
//! [`super::Material::DEFAULT`]. Materials are mapped as in [`super::mtl`]; every material of
//! every library is kept (distinct values once), used or not. The merge into one world space is
//! [`super::geometry`]'s.
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

use super::geometry::{read_regular_file, MeshPart, SceneGeometry, NO_MATERIAL};
use super::mtl::{material_from_mtl, parse_mtl, preview, MtlLibrary, MtlMaterial};
use super::text::{decode, is_keyword, line_error, logical_lines, statement, StatementCounts};
use super::SceneError;

/// One OBJ file, parsed but not yet added to a [`SceneGeometry`].
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
        let at_line = line_error(path, number);
        let line = line.trim();
        let Some((keyword, words)) = statement(line) else {
            continue;
        };
        // Arguments end at a word starting with `#` (a trailing comment).
        let args = words.take_while(|w| !w.starts_with('#'));
        match keyword {
            "v" => {
                let p = vertex(args, &mut file).map_err(&at_line)?;
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
                let libraries = libraries(name, resolve, &mut file, &mut missing_seen)?;
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

/// The position of a `v` statement from its arguments: `x y z`, `x y z w` (divided by `w`) or
/// `x y z r g b` (the colour counted in `file.ignored`).
fn vertex<'a>(args: impl Iterator<Item = &'a str>, file: &mut ObjFile) -> Result<Vec3, String> {
    let mut values = [0.0f32; 7];
    let mut n = 0;
    for word in args {
        if n == values.len() {
            n += 1;
            break;
        }
        values[n] = word
            .parse()
            .map_err(|_| format!("'{}' is not a number (vertex coordinate)", preview(word)))?;
        n += 1;
    }
    let p = Vec3::new(values[0], values[1], values[2]);
    match n {
        3 => Ok(p),
        4 => Ok(p / values[3]),
        6 => {
            file.ignored.add("v rgb", 1);
            Ok(p)
        }
        _ => Err(format!(
            "a vertex needs x y z, x y z w or x y z r g b; found {} numbers",
            if n > values.len() {
                format!("more than {}", values.len())
            } else {
                n.to_string()
            }
        )),
    }
}

/// The material libraries an `mtllib` statement names: `name` whole, or, when that file does
/// not exist and the name has spaces, each word; the names found nowhere are added once to
/// `file.missing_mtl`.
fn libraries(
    name: &str,
    resolve: &mut LibraryResolver<'_>,
    file: &mut ObjFile,
    missing_seen: &mut HashSet<String>,
) -> Result<Vec<Arc<MtlLibrary>>, SceneError> {
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
    Ok(libraries)
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

/// Reads OBJ files into a [`SceneGeometry`], reading and parsing each material library once
/// per load however many files name it.
#[derive(Debug, Clone, Default)]
pub struct ObjReader {
    /// Libraries read so far by path (`None`: no such file).
    libraries: HashMap<PathBuf, Option<Arc<MtlLibrary>>>,
}

impl ObjReader {
    /// A reader that has read no library yet.
    pub fn new() -> Self {
        ObjReader::default()
    }

    /// Append the OBJ file at `path` (its `mtllib`s are resolved relative to its folder) to
    /// `geometry` and return the number of triangles it added. On error nothing is appended.
    ///
    /// Errors: [`SceneError::Io`] when the file (or an existing material library) cannot be
    /// read or is not a regular file; [`SceneError::Parse`] naming the file and line for broken
    /// OBJ or MTL data (see the module documentation and [`super::mtl`]).
    pub fn load_file(
        &mut self,
        geometry: &mut SceneGeometry,
        path: &Path,
    ) -> Result<usize, SceneError> {
        let bytes = read_regular_file(path)?;
        let text = decode(&bytes, path)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let file = parse_obj(&text, path, &mut |name| {
            self.library(&mut geometry.mtl_ignored, dir.join(name))
        })?;
        add_obj(geometry, file, path)
    }

    /// The library at `full`, read and parsed on first use (`None` when no such file exists);
    /// its unused statements are counted in `mtl_ignored` when it is first read.
    fn library(
        &mut self,
        mtl_ignored: &mut StatementCounts,
        full: PathBuf,
    ) -> Result<Option<Arc<MtlLibrary>>, SceneError> {
        if let Some(known) = self.libraries.get(&full) {
            return Ok(known.clone());
        }
        let library = match read_regular_file(&full) {
            Ok(bytes) => {
                let library = parse_mtl(&decode(&bytes, &full)?, &full)?;
                mtl_ignored.merge(&library.ignored);
                Some(Arc::new(library))
            }
            Err(SceneError::Io { .. }) if !full.exists() => None,
            Err(err) => return Err(err),
        };
        self.libraries.insert(full, library.clone());
        Ok(library)
    }
}

/// Append OBJ file `path`, parsed, to `geometry` (its missing libraries named relative to the
/// file's folder) and return the number of triangles it added; see
/// [`SceneGeometry::add_part`]. On error nothing is appended.
pub fn add_obj(
    geometry: &mut SceneGeometry,
    file: ObjFile,
    path: &Path,
) -> Result<usize, SceneError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let part = MeshPart {
        vertices: file.vertices,
        triangles: file.triangles,
        tri_slot: file.tri_slot,
        materials: file.materials.iter().map(material_from_mtl).collect(),
        nonfinite_vertices: file.nonfinite_vertices,
    };
    let added = geometry.add_part(&part, path)?;
    geometry.ignored.merge(&file.ignored);
    for name in file.missing_mtl {
        geometry.note_missing_library(dir.join(name));
    }
    for name in file.undefined_materials {
        geometry.note_undefined_material(name);
    }
    Ok(added)
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
