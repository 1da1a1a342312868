//! Valid glTF and PLY files the fuzzer mutates, generated from the run's seed: glTF with its
//! buffer as a base64 `data:` URI, in a GLB binary chunk, or partly in the external buffer file
//! every fuzz case resolves to ([`fuzz_buffer`]); node hierarchies with every kind of
//! transform, cameras, materials with extensions and textures, indexed and non-indexed
//! primitives of several modes, strided and sparse accessors. PLY in ASCII and binary little-
//! and big-endian, with every number type for coordinates and face lists, unused properties
//! and elements, comments and polygons.

use std::sync::OnceLock;

use base64::engine::general_purpose::STANDARD;
use base64::Engine;
use serde_json::{json, Value};

use super::mutate::Rng;

/// The bytes every relative buffer URI of a fuzzed glTF file resolves to (names starting with
/// `missing` resolve to no file): a cube's 8 positions (`f32`, 96 bytes) then its 36 `u16`
/// indices (72 bytes).
pub fn fuzz_buffer() -> &'static [u8] {
    static BUFFER: OnceLock<Vec<u8>> = OnceLock::new();
    BUFFER.get_or_init(|| {
        let mut bytes = Vec::new();
        for i in 0..8u32 {
            for axis in 0..3 {
                bytes.extend((((i >> axis) & 1) as f32).to_le_bytes());
            }
        }
        let quads = [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ];
        for [a, b, c, d] in quads {
            for v in [a, b, c, a, c, d] {
                bytes.extend((v as u16).to_le_bytes());
            }
        }
        bytes
    })
}

/// The buffer, views, accessors and primitives of a glTF seed being built.
#[derive(Default)]
struct Builder {
    /// The binary buffer 0.
    bin: Vec<u8>,
    /// `bufferViews`.
    views: Vec<Value>,
    /// `accessors`.
    accessors: Vec<Value>,
}

impl Builder {
    /// Append `bytes` (4-byte aligned) as a buffer view of buffer 0 with `stride`, and return
    /// its index.
    fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut view = json!({"buffer": 0, "byteOffset": self.bin.len(),
                              "byteLength": bytes.len()});
        if let Some(stride) = stride {
            view["byteStride"] = json!(stride);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    /// Add `accessor` and return its index.
    fn accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// A `POSITION` accessor of `points`, `stride` bytes apart (12 written without a stride
    /// 1 time in 2), sometimes with sparse values replacing some of them.
    fn positions(&mut self, rng: &mut Rng, points: &[[f32; 3]], stride: usize) -> usize {
        let mut bytes = Vec::new();
        for p in points {
            for c in p {
                bytes.extend(c.to_le_bytes());
            }
            bytes.resize(bytes.len() + stride - 12, 0);
        }
        let written = (stride != 12 || rng.chance(50)).then_some(stride);
        let view = self.view(&bytes, written);
        let mut accessor = json!({"bufferView": view, "componentType": 5126, "type": "VEC3",
                                  "count": points.len(), "min": bound(points, f32::min),
                                  "max": bound(points, f32::max)});
        if rng.chance(25) {
            accessor["sparse"] = self.sparse(rng, points.len());
        }
        self.accessor(accessor)
    }

    /// A sparse block replacing 1 to 3 of `count` elements with small positions.
    fn sparse(&mut self, rng: &mut Rng, count: usize) -> Value {
        let n = 1 + rng.below(3.min(count));
        let first = rng.below(count + 1 - n);
        let (component, size) = *rng.pick(&[(5121, 1), (5123, 2), (5125, 4)]);
        let mut indices = Vec::new();
        for k in 0..n {
            let i = (first + k) as u32;
            indices.extend(&i.to_le_bytes()[..size]);
        }
        let mut values = Vec::new();
        for _ in 0..3 * n {
            values.extend(rng.float().to_le_bytes());
        }
        let indices = self.view(&indices, None);
        let values = self.view(&values, None);
        json!({"count": n, "indices": {"bufferView": indices, "componentType": component},
               "values": {"bufferView": values}})
    }

    /// An index accessor of `indices` in the smallest or a random wider unsigned type.
    fn indices(&mut self, rng: &mut Rng, indices: &[u32], vertices: usize) -> usize {
        let types: &[(u32, usize)] = if vertices <= 256 {
            &[(5121, 1), (5123, 2), (5125, 4)]
        } else {
            &[(5123, 2), (5125, 4)]
        };
        let (component, size) = *rng.pick(types);
        let mut bytes = Vec::new();
        for &i in indices {
            bytes.extend(&i.to_le_bytes()[..size]);
        }
        let view = self.view(&bytes, None);
        self.accessor(json!({"bufferView": view, "componentType": component,
                             "type": "SCALAR", "count": indices.len()}))
    }
}

/// The per-axis minimum or maximum (`pick`) of `points`.
fn bound(points: &[[f32; 3]], pick: fn(f32, f32) -> f32) -> [f32; 3] {
    points.iter().fold(points[0], |acc, p| {
        [pick(acc[0], p[0]), pick(acc[1], p[1]), pick(acc[2], p[2])]
    })
}

/// A random position.
fn point(rng: &mut Rng) -> [f32; 3] {
    [rng.float(), rng.float(), rng.float()]
}

/// A number in `[-10, 10]` in steps of 0.1, for transforms (which must keep a camera's view
/// valid).
fn small(rng: &mut Rng) -> f32 {
    (rng.below(201) as f32 - 100.0) / 10.0
}

/// A glTF seed; `variant` picks the container: a `data:` URI, a GLB, or a `data:` URI plus a
/// second buffer in the external file (a cube, [`fuzz_buffer`]).
pub fn gltf(rng: &mut Rng, variant: usize) -> Vec<u8> {
    let mut b = Builder::default();
    let n = 3 + rng.below(20);
    let points: Vec<[f32; 3]> = (0..n).map(|_| point(rng)).collect();
    let stride = *rng.pick(&[12, 12, 16, 20]);
    let positions = b.positions(rng, &points, stride);
    let triangles = 1 + rng.below(12);
    let indices: Vec<u32> = (0..3 * triangles).map(|_| rng.below(n) as u32).collect();
    let materials = rng.below(4);
    let mut primitives = Vec::new();
    for p in 0..1 + rng.below(3) {
        let mut primitive = json!({"attributes": {"POSITION": positions}});
        if p > 0 && rng.chance(30) {
            primitive["mode"] = json!(rng.below(7));
        }
        if rng.chance(20) {
            primitive["attributes"]["NORMAL"] = json!(positions);
        }
        if rng.chance(60) || !n.is_multiple_of(3) {
            primitive["indices"] = json!(b.indices(rng, &indices, n));
        }
        if materials > 0 && rng.chance(70) {
            primitive["material"] = json!(rng.below(materials));
        }
        primitives.push(primitive);
    }
    if rng.chance(20) {
        // Zeros and a sparse block, without a buffer view.
        let count = 3 * (1 + rng.below(3));
        let sparse = b.sparse(rng, count);
        let accessor = b.accessor(json!({"componentType": 5126, "type": "VEC3",
                                         "count": count, "min": [-10, -10, -10],
                                         "max": [10, 10, 10], "sparse": sparse}));
        primitives.push(json!({"attributes": {"POSITION": accessor}}));
    }
    let mut meshes = vec![json!({"primitives": primitives})];
    let mut buffers = Vec::new();
    if variant % 3 == 2 {
        let cube = fuzz_buffer();
        let pos = b.views.len();
        b.views.extend([
            json!({"buffer": 1, "byteOffset": 0, "byteLength": 96}),
            json!({"buffer": 1, "byteOffset": 96, "byteLength": 72}),
        ]);
        let accessor = b.accessor(json!({"bufferView": pos, "componentType": 5126,
                                         "type": "VEC3", "count": 8, "min": [0, 0, 0],
                                         "max": [1, 1, 1]}));
        let idx = b.accessor(json!({"bufferView": pos + 1, "componentType": 5123,
                                    "type": "SCALAR", "count": 36}));
        meshes.push(json!({"primitives": [{"attributes": {"POSITION": accessor},
                                           "indices": idx}]}));
        buffers.push(json!({"byteLength": cube.len(), "uri": "fuzz%20cube.bin"}));
    }
    let (nodes, roots) = nodes(rng, meshes.len());
    let glb = variant % 3 == 1;
    let mut buffer = json!({"byteLength": b.bin.len()});
    if !glb {
        buffer["uri"] = json!(format!(
            "data:application/octet-stream;base64,{}",
            STANDARD.encode(&b.bin)
        ));
    }
    buffers.insert(0, buffer);
    let mut scenes = vec![json!({"nodes": roots})];
    if rng.chance(20) {
        scenes.push(json!({"nodes": [0]}));
    }
    let materials: Vec<Value> = (0..materials).map(|_| material(rng)).collect();
    let yfov = 0.2 + rng.below(20) as f32 / 10.0;
    let mut document = json!({
        "asset": {"version": "2.0", "generator": "vtq fuzz"},
        "scenes": scenes,
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{"source": 0}],
        "images": [{"uri": "texture.png"}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.01}},
                    {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1,
                                                               "znear": 0.01, "zfar": 100}}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": buffers,
    });
    if rng.chance(70) {
        document["scene"] = json!(0);
    }
    if rng.chance(50) {
        document["extensionsUsed"] = json!([
            "KHR_materials_emissive_strength",
            "KHR_materials_transmission",
            "KHR_materials_ior",
            "KHR_texture_transform"
        ]);
    }
    let text = document.to_string();
    if glb {
        glb_file(text.as_bytes(), &b.bin)
    } else {
        text.into_bytes()
    }
}

/// 1 to 6 nodes: every one with a transform of some kind, some with children, one of the
/// first meshes each 2 in 3, a camera 1 in 5; and the root nodes (at least one holds mesh 0).
fn nodes(rng: &mut Rng, meshes: usize) -> (Vec<Value>, Vec<usize>) {
    let count = 1 + rng.below(6);
    let mut nodes = Vec::new();
    for i in 0..count {
        let mut node = match rng.below(4) {
            0 => json!({}),
            1 => json!({"translation": [small(rng), small(rng), small(rng)]}),
            2 => {
                let q = [small(rng), small(rng), small(rng), 1.0 + small(rng).abs()];
                let norm = q.iter().map(|x| x * x).sum::<f32>().sqrt();
                let scale = 0.5 + rng.below(4) as f32 / 2.0;
                json!({"rotation": q.map(|x| x / norm), "scale": [scale, scale, scale]})
            }
            _ => {
                let t = [small(rng), small(rng), small(rng)];
                json!({"matrix": [2,0,0,0, 0,1,0,0, 0,0,1,0, t[0],t[1],t[2],1]})
            }
        };
        if i == 0 || rng.chance(65) {
            node["mesh"] = json!(if i == 0 { 0 } else { rng.below(meshes) });
        }
        if rng.chance(20) {
            node["camera"] = json!(rng.below(2));
        }
        nodes.push(node);
    }
    // Each later node is a child of an earlier one or a root: the nodes form trees.
    let mut roots = vec![0];
    for i in 1..count {
        if rng.chance(50) {
            roots.push(i);
        } else {
            let parent = rng.below(i);
            let children = nodes[parent]
                .as_object_mut()
                .expect("a node is an object")
                .entry("children")
                .or_insert_with(|| json!([]));
            children
                .as_array_mut()
                .expect("children are an array")
                .push(json!(i));
        }
    }
    (nodes, roots)
}

/// A material with a random choice of factors, extensions, textures and alpha mode.
fn material(rng: &mut Rng) -> Value {
    let unit = |rng: &mut Rng| rng.below(1001) as f32 / 1000.0;
    let mut pbr = json!({"baseColorFactor": [unit(rng), unit(rng), unit(rng), unit(rng)]});
    for key in ["metallicFactor", "roughnessFactor"] {
        if rng.chance(60) {
            pbr[key] = json!(unit(rng));
        }
    }
    if rng.chance(20) {
        pbr["baseColorTexture"] = json!({"index": 0});
    }
    let mut m = json!({"pbrMetallicRoughness": pbr});
    if rng.chance(20) {
        m["emissiveFactor"] = json!([unit(rng), unit(rng), unit(rng)]);
    }
    if rng.chance(20) {
        m["normalTexture"] = json!({"index": 0, "scale": 1});
    }
    if rng.chance(20) {
        m["alphaMode"] = json!(*rng.pick(&["OPAQUE", "MASK", "BLEND"]));
    }
    let mut extensions = serde_json::Map::new();
    if rng.chance(20) {
        extensions.insert(
            "KHR_materials_emissive_strength".into(),
            json!({"emissiveStrength": 1 + rng.below(10)}),
        );
    }
    if rng.chance(20) {
        extensions.insert(
            "KHR_materials_transmission".into(),
            json!({"transmissionFactor": unit(rng)}),
        );
        extensions.insert("KHR_materials_ior".into(), json!({"ior": 1.0 + unit(rng)}));
    }
    if !extensions.is_empty() {
        m["extensions"] = Value::Object(extensions);
    }
    m
}

/// A GLB file of `json` (padded with spaces) and `bin` (padded with zeros).
fn glb_file(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |n: usize| n.div_ceil(4) * 4;
    let (json_len, bin_len) = (pad(json.len()), pad(bin.len()));
    let total = 12 + 8 + json_len + 8 + bin_len;
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json_len as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.resize(20 + json_len, b' ');
    out.extend((bin_len as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out.resize(total, 0);
    out
}

/// Repair the lengths of a mutated GLB file (three in four GLB cases), so that mutations reach
/// the JSON and the accessors behind the container: the JSON chunk runs to the last `BIN\0`
/// chunk type (or to the end), the binary chunk to the end, and the header's total is the
/// file's length.
pub fn reseal_glb(input: &mut [u8]) {
    if !input.starts_with(b"glTF") || input.len() < 20 {
        return;
    }
    let len = input.len();
    let bin_type = input[20..]
        .windows(4)
        .rposition(|w| w == b"BIN\0")
        .map(|p| p + 20)
        .filter(|&p| p >= 24);
    let json_end = bin_type.map_or(len, |p| p - 4);
    input[8..12].copy_from_slice(&(len as u32).to_le_bytes());
    input[12..16].copy_from_slice(&((json_end - 20) as u32).to_le_bytes());
    if let Some(p) = bin_type {
        input[p - 4..p].copy_from_slice(&((len - p - 4) as u32).to_le_bytes());
    }
}

/// End an ASCII data line (its last value's trailing blank becomes the line end).
fn end_line(out: &mut Vec<u8>, ascii: bool) {
    if ascii {
        if out.last() == Some(&b' ') {
            out.pop();
        }
        out.push(b'\n');
    }
}

/// A PLY scalar type name and its size in bytes.
type PlyType = (&'static str, usize);

/// A PLY seed; `variant` picks the encoding (ASCII, binary little-endian, binary big-endian).
pub fn ply(rng: &mut Rng, variant: usize) -> Vec<u8> {
    let n = 3 + rng.below(20);
    let faces: Vec<Vec<u32>> = (0..1 + rng.below(12))
        .map(|_| {
            let corners = 3 + if rng.chance(70) { 0 } else { rng.below(4) };
            (0..corners).map(|_| rng.below(n) as u32).collect()
        })
        .collect();
    let encoding = ["ascii", "binary_little_endian", "binary_big_endian"][variant % 3];
    let coordinate: PlyType = *rng.pick(&[("float", 4), ("double", 8), ("float32", 4)]);
    let count_type: PlyType = *rng.pick(&[("uchar", 1), ("ushort", 2), ("uint", 4), ("uint8", 1)]);
    let index_type: PlyType = *rng.pick(&[("int", 4), ("uint", 4), ("int32", 4), ("ushort", 2)]);
    let list_name = *rng.pick(&["vertex_indices", "vertex_index"]);
    let colours = rng.chance(40);
    let edges = rng.below(3) * usize::from(rng.chance(30));
    let mut header = format!("ply\nformat {encoding} 1.0\ncomment vtq fuzz seed\n");
    if rng.chance(30) {
        header.push_str("obj_info generated\n");
    }
    header.push_str(&format!("element vertex {n}\n"));
    for axis in ["x", "y", "z"] {
        header.push_str(&format!("property {} {axis}\n", coordinate.0));
    }
    if colours {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str(&format!(
        "element face {}\nproperty list {} {} {list_name}\n",
        faces.len(),
        count_type.0,
        index_type.0
    ));
    if edges > 0 {
        header.push_str(&format!(
            "element edge {edges}\nproperty int vertex1\nproperty int vertex2\n"
        ));
    }
    header.push_str("end_header\n");
    let mut out = header.into_bytes();
    let ascii = variant.is_multiple_of(3);
    let big = variant % 3 == 2;
    let put = |out: &mut Vec<u8>, value: f64, (name, size): PlyType| {
        if ascii {
            out.extend(format!("{value} ").bytes());
            return;
        }
        let le: Vec<u8> = match (name, size) {
            ("double", _) => value.to_le_bytes().to_vec(),
            (_, 4) if name.starts_with("float") => (value as f32).to_le_bytes().to_vec(),
            (_, size) => (value as i64 as u64).to_le_bytes()[..size].to_vec(),
        };
        if big {
            out.extend(le.iter().rev());
        } else {
            out.extend(le);
        }
    };
    for _ in 0..n {
        for _ in 0..3 {
            put(&mut out, f64::from(rng.float()), coordinate);
        }
        if colours {
            for _ in 0..3 {
                put(&mut out, rng.below(256) as f64, ("uchar", 1));
            }
        }
        end_line(&mut out, ascii);
    }
    for face in &faces {
        put(&mut out, face.len() as f64, count_type);
        for &v in face {
            put(&mut out, f64::from(v), index_type);
        }
        end_line(&mut out, ascii);
    }
    for e in 0..edges {
        put(&mut out, e as f64, ("int", 4));
        put(&mut out, (e + 1) as f64, ("int", 4));
        end_line(&mut out, ascii);
    }
    out
}
