//! PLY (Stanford polygon) meshes, ASCII and binary little- or big-endian, read with the
//! `ply-rs-bw` crate.
//!
//! # What is read
//! The `vertex` element's scalar properties `x`, `y` and `z` (any number type; converted to
//! `f32`) as positions, and the `face` element's list property `vertex_indices` (or
//! `vertex_index`, as some writers name it; any integer type) as polygons, fan-triangulated as
//! OBJ faces are: `(v0, v1, v2), (v0, v2, v3), ...`, faces in file order. Every triangle gets
//! vtq's default grey Lambertian material.
//!
//! # What is counted, not used
//! Every other property of `vertex` and `face` (colours `red`/`green`/`blue`/`alpha`, normals
//! `nx`/`ny`/`nz`, texture coordinates, `flags`, ...), counted as `vertex red`, `face flags`,
//! ... once per element, and every other element (`edge`, `material`, `tristrips`, ...) as
//! `element NAME` once per instance. Comments and `obj_info` lines are not counted, as OBJ
//! comments are not. A vertex whose position is not finite is not an error: it is counted, and
//! every triangle using it is left out and counted (see [`super::geometry`]).
//!
//! # Errors
//! A malformed file is a [`SceneError::Parse`] naming the file (and the line where the reader
//! knows it), never a panic: a header that does not parse, no `vertex` element or one without
//! scalar `x`, `y` and `z`, no `face` element (a point cloud: nothing to render) or one without
//! an integer `vertex_indices` list, data that ends early or does not match the header, a face
//! with fewer than 3 vertices, or a vertex index that is negative or out of range.

use std::io::BufRead;
use std::path::Path;

use glam::Vec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType,
};

use super::geometry::{read_regular_file, MeshPart, NO_MATERIAL};
use super::mtl::preview;
use super::text::StatementCounts;
use super::SceneError;

/// The names of the face list of vertex indices, in the order they are looked for.
const FACE_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];

/// The longest reader message kept in an error (it may quote a whole data line).
const MAX_MESSAGE: usize = 200;

/// What one PLY file adds to a scene.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlyFile {
    /// The triangles, all with the default material.
    pub part: MeshPart,
    /// Properties and elements read but not used, by kind.
    pub ignored: StatementCounts,
}

/// Read the PLY file at `path` (see [`parse_ply`]).
///
/// Errors: [`SceneError::Io`] when the file cannot be read, else as [`parse_ply`].
pub fn read_ply_file(path: &Path) -> Result<PlyFile, SceneError> {
    parse_ply(&read_regular_file(path)?, path)
}

/// Parse a PLY file's bytes; `path` names the file in errors. See the module documentation for
/// what is read, counted and refused.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<PlyFile, SceneError> {
    let fail = |reason: String| SceneError::Parse {
        path: path.display().to_string(),
        reason,
    };
    let mut reader = Reader::new(bytes);
    let header = Parser::<Vertex>::new()
        .read_header(&mut reader)
        .map_err(|e| fail(format!("invalid PLY header: {}", shorten(&e.to_string()))))?;
    let face_list = check_header(&header).map_err(&fail)?;
    let mut file = PlyFile::default();
    let mut faces = Vec::new();
    for element in header.elements.values() {
        let what = |e: ply_rs_bw::parser::ParseError| {
            fail(format!(
                "{} data: {}",
                element.name,
                shorten(&e.to_string())
            ))
        };
        match element.name.as_str() {
            "vertex" => {
                let vertices = Parser::<Vertex>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(what)?;
                file.part.vertices = vertices.into_iter().map(|v| v.position()).collect();
                count_unused(&mut file.ignored, element, &["x", "y", "z"]);
            }
            "face" => {
                faces = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(what)?;
                count_unused(&mut file.ignored, element, &[face_list]);
            }
            _ => {
                skip(&mut reader, element, &header).map_err(what)?;
                if element.count > 0 {
                    file.ignored.add(
                        &format!("element {}", preview(&element.name)),
                        element.count as u64,
                    );
                }
            }
        }
    }
    let part = &mut file.part;
    part.nonfinite_vertices = part.vertices.iter().filter(|p| !p.is_finite()).count() as u64;
    let n_vertices = part.vertices.len();
    for (k, face) in faces.iter().enumerate() {
        if let Some(bad) = face.negative {
            return Err(fail(format!("face {k}: vertex index {bad} is negative")));
        }
        if face.indices.len() < 3 {
            return Err(fail(format!(
                "face {k} has {} vertices; a face needs at least 3",
                face.indices.len()
            )));
        }
        if let Some(&bad) = face.indices.iter().find(|&&v| v as usize >= n_vertices) {
            return Err(fail(format!(
                "face {k}: vertex index {bad} is out of range ({n_vertices} vertices)"
            )));
        }
        for pair in face.indices[1..].windows(2) {
            part.triangles.push([face.indices[0], pair[0], pair[1]]);
            part.tri_slot.push(NO_MATERIAL);
        }
    }
    Ok(file)
}

/// Check that the header has what vtq reads, and return the name of the face list.
fn check_header(header: &Header) -> Result<&'static str, String> {
    let vertex = header
        .elements
        .get("vertex")
        .ok_or("no 'vertex' element in the header")?;
    for axis in ["x", "y", "z"] {
        match vertex.properties.get(axis).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(format!("vertex property '{axis}' is a list, not a number"))
            }
            None => return Err(format!("the vertex element has no '{axis}' property")),
        }
    }
    let face = header.elements.get("face").ok_or(
        "no 'face' element in the header: a point cloud has nothing to render (vtq renders \
         triangles)",
    )?;
    let (name, property) = FACE_LISTS
        .iter()
        .find_map(|&name| face.properties.get(name).map(|p| (name, p)))
        .ok_or("the face element has no vertex_indices (or vertex_index) list")?;
    match property.data_type {
        PropertyType::List(_, ScalarType::Float | ScalarType::Double) => Err(format!(
            "face property '{name}' is a list of floating-point numbers, not of integers"
        )),
        PropertyType::List(..) => Ok(name),
        PropertyType::Scalar(_) => Err(format!("face property '{name}' is not a list")),
    }
}

/// Count the properties of `element` other than `used`, once per element instance.
fn count_unused(ignored: &mut StatementCounts, element: &ElementDef, used: &[&str]) {
    if element.count == 0 {
        return;
    }
    for name in element.properties.keys() {
        if !used.contains(&name.as_str()) {
            ignored.add(
                &format!("{} {}", preview(&element.name), preview(name)),
                element.count as u64,
            );
        }
    }
}

/// Read past the data of an element vtq does not use. A binary element without properties
/// has no data (so its count, however large, costs nothing).
fn skip<T: BufRead>(
    reader: &mut Reader<T>,
    element: &ElementDef,
    header: &Header,
) -> Result<(), ply_rs_bw::parser::ParseError> {
    if element.properties.is_empty() && header.encoding != Encoding::Ascii {
        return Ok(());
    }
    Parser::<Skipped>::new()
        .read_payload_for_element(reader, element, header)
        .map(drop)
}

/// `message` cut to [`MAX_MESSAGE`] characters, on one line.
fn shorten(message: &str) -> String {
    let one_line = message.split_whitespace().collect::<Vec<_>>().join(" ");
    if one_line.chars().count() <= MAX_MESSAGE {
        one_line
    } else {
        format!(
            "{}...",
            one_line.chars().take(MAX_MESSAGE).collect::<String>()
        )
    }
}

/// A vertex as read: its coordinates (other properties are not stored).
#[derive(Debug, Clone, Copy, Default)]
struct Vertex([f64; 3]);

impl Vertex {
    /// The position as `f32` (a coordinate beyond `f32` becomes infinite).
    fn position(self) -> Vec3 {
        Vec3::new(self.0[0] as f32, self.0[1] as f32, self.0[2] as f32)
    }

    /// Store coordinate `name` (`x`, `y` or `z`).
    fn set(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        self.0[axis] = value;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }
    fn set_char(&mut self, name: &str, value: i8) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_uchar(&mut self, name: &str, value: u8) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_short(&mut self, name: &str, value: i16) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_ushort(&mut self, name: &str, value: u16) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_int(&mut self, name: &str, value: i32) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_uint(&mut self, name: &str, value: u32) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_float(&mut self, name: &str, value: f32) -> PropertyAccessResult {
        self.set(name, value.into())
    }
    fn set_double(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        self.set(name, value)
    }
}

/// A face as read: its vertex indices, and the first negative one if any.
#[derive(Debug, Clone, Default)]
struct Face {
    /// The vertex indices (a negative one is stored as 0 and recorded in `negative`).
    indices: Vec<u32>,
    /// The first negative index, which makes the file invalid.
    negative: Option<i64>,
}

impl Face {
    /// Store the index list if `name` is the face list.
    fn set<I: Copy + Into<i64>>(&mut self, name: &str, values: &[I]) -> PropertyAccessResult {
        if !FACE_LISTS.contains(&name) {
            return PropertyAccessResult::Ignored;
        }
        self.indices.clear();
        self.indices.extend(values.iter().map(|&v| {
            let v: i64 = v.into();
            u32::try_from(v).unwrap_or_else(|_| {
                self.negative.get_or_insert(v);
                0
            })
        }));
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn set_list_char(&mut self, name: &str, value: Vec<i8>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_uchar(&mut self, name: &str, value: Vec<u8>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_short(&mut self, name: &str, value: Vec<i16>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_ushort(&mut self, name: &str, value: Vec<u16>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_int(&mut self, name: &str, value: Vec<i32>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_uint(&mut self, name: &str, value: Vec<u32>) -> PropertyAccessResult {
        self.set(name, &value)
    }
}

/// An element vtq does not use: every property is read and dropped.
struct Skipped;

impl PropertyAccess for Skipped {
    fn new() -> Self {
        Skipped
    }
}
