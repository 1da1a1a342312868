//! A small test mesh and writers that put it in every scene format vtq reads: OBJ + MTL, glTF
//! with embedded (base64) or separate buffers, GLB, and PLY in ASCII and binary little- and
//! big-endian. Shared by the glTF/PLY scene tests.

// Each test binary compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

/// A polygon mesh: positions, and faces (3 or more corners, 0-based) grouped by material.
#[derive(Debug, Clone)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Face groups: the material (an index into [`MATERIALS`], or `None` for the default) and
    /// its polygons.
    pub groups: Vec<(Option<usize>, Vec<Vec<u32>>)>,
}

/// The test materials, in the same order in the MTL library and the glTF file: a red diffuse,
/// a lamp, a rough metal and a glass.
pub const MATERIALS: [&str; 4] = ["red", "lamp", "steel", "glass"];

/// A floor, a back wall, a box, a ceiling lamp and a glass pyramid: 21 triangles from
/// quadrilaterals and triangles, with every material and faces without one.
pub fn room() -> Mesh {
    let mut positions = vec![
        // Floor 0-3.
        [-2.0, 0.0, -2.0],
        [2.0, 0.0, -2.0],
        [2.0, 0.0, 2.0],
        [-2.0, 0.0, 2.0],
        // Back wall top 4-5 (its bottom is the floor's back edge).
        [2.0, 3.0, -2.0],
        [-2.0, 3.0, -2.0],
        // Lamp 6-9.
        [-0.5, 2.75, -0.5],
        [0.5, 2.75, -0.5],
        [0.5, 2.75, 0.5],
        [-0.5, 2.75, 0.5],
        // Pyramid 10-13.
        [1.0, 0.0, 0.5],
        [1.5, 0.0, 1.25],
        [0.5, 0.0, 1.25],
        [1.0, 0.75, 1.0],
    ];
    // Box 14-21: bottom square then top square.
    for y in [0.0, 1.0] {
        positions.extend([
            [-1.5, y, -1.0],
            [-0.5, y, -1.0],
            [-0.5, y, 0.0],
            [-1.5, y, 0.0],
        ]);
    }
    let b = |i: u32| 14 + i;
    let box_faces = vec![
        vec![b(4), b(7), b(6), b(5)],
        vec![b(0), b(1), b(5), b(4)],
        vec![b(1), b(2), b(6), b(5)],
        vec![b(2), b(3), b(7), b(6)],
        vec![b(3), b(0), b(4), b(7)],
        vec![b(0), b(3), b(2), b(1)],
    ];
    Mesh {
        positions,
        groups: vec![
            (None, vec![vec![0, 1, 4, 5]]),
            (Some(0), vec![vec![3, 2, 1, 0]]),
            (Some(2), box_faces),
            (Some(1), vec![vec![6, 7, 8, 9]]),
            (
                Some(3),
                vec![vec![10, 11, 13], vec![11, 12, 13], vec![12, 10, 13]],
            ),
        ],
    }
}

impl Mesh {
    /// The mesh with every face group on the default material.
    pub fn without_materials(&self) -> Mesh {
        Mesh {
            positions: self.positions.clone(),
            groups: self
                .groups
                .iter()
                .map(|(_, faces)| (None, faces.clone()))
                .collect(),
        }
    }

    /// The triangles of each group, polygons as fans `(v0, v1, v2), (v0, v2, v3), ...`.
    pub fn fan_triangles(&self) -> Vec<(Option<usize>, Vec<u32>)> {
        self.groups
            .iter()
            .map(|(material, faces)| {
                let mut indices = Vec::new();
                for face in faces {
                    for pair in face[1..].windows(2) {
                        indices.extend([face[0], pair[0], pair[1]]);
                    }
                }
                (*material, indices)
            })
            .collect()
    }
}

/// Write `bytes` to `dir/name` and return the path.
pub fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write test file");
    path
}

/// A fresh, empty temporary folder unique to this process and `tag`: the shared tests'
/// [`crate::common::fresh_dir`] named `vtq-gltf-ply-<tag>-<process id>`.
pub fn temp_dir(tag: &str) -> PathBuf {
    crate::common::fresh_dir(&format!("gltf-ply-{tag}"))
}

/// The MTL library of [`MATERIALS`].
pub const MTL: &str = "newmtl red\nKd 0.75 0.25 0.25\n\
    newmtl lamp\nKe 4 4 4\n\
    newmtl steel\nKd 0.5 0.5 0.75\nPm 1\nPr 0.25\n\
    newmtl glass\nNi 1.5\nd 0.1\n";

/// The mesh as OBJ text (with `mtllib scene.mtl` when a group has a material).
pub fn obj(mesh: &Mesh) -> String {
    let mut s = String::new();
    if mesh.groups.iter().any(|(m, _)| m.is_some()) {
        s.push_str("mtllib scene.mtl\n");
    }
    for p in &mesh.positions {
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for (material, faces) in &mesh.groups {
        s.push_str(&format!(
            "usemtl {}\n",
            material.map_or("", |m| MATERIALS[m])
        ));
        for face in faces {
            let corners: Vec<String> = face.iter().map(|v| (v + 1).to_string()).collect();
            s.push_str(&format!("f {}\n", corners.join(" ")));
        }
    }
    s
}

/// The glTF materials of [`MATERIALS`].
fn gltf_materials() -> Value {
    json!([
        {"pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.25, 0.25, 1.0], "metallicFactor": 0.0}},
        {"emissiveFactor": [1.0, 1.0, 1.0],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
        {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.75, 1.0],
                                  "metallicFactor": 1.0, "roughnessFactor": 0.25}},
        {"extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_ior": {"ior": 1.5}}}
    ])
}

/// The mesh as a glTF document and its binary buffer. Positions are one accessor (elements
/// `stride` bytes apart) that every primitive indexes, with indices of a different type per
/// group (u16, u32, u8 in turn), except the lamp group, which is written without indices (its
/// own positions, three per triangle). `uri` is the buffer's URI (`None`: the GLB chunk).
pub fn gltf(mesh: &Mesh, stride: usize, uri: Option<String>) -> (Value, Vec<u8>) {
    assert!(stride >= 12 && stride.is_multiple_of(4));
    let mut bin = Vec::new();
    for p in &mesh.positions {
        for c in p {
            bin.extend(c.to_le_bytes());
        }
        bin.resize(bin.len() + stride - 12, 0);
    }
    let n = mesh.positions.len();
    let mut views = vec![
        json!({"buffer": 0, "byteOffset": 0, "byteLength": n * stride,
                                "byteStride": stride}),
    ];
    let mut accessors = vec![json!({"bufferView": 0, "componentType": 5126, "count": n,
                                    "type": "VEC3", "min": bound(&mesh.positions, f32::min),
                                    "max": bound(&mesh.positions, f32::max)})];
    let mut primitives = Vec::new();
    for (g, (material, indices)) in mesh.fan_triangles().into_iter().enumerate() {
        let start = bin.len();
        let mut attributes = json!({"POSITION": 0});
        let mut primitive = json!({});
        if material == Some(1) {
            let corners: Vec<[f32; 3]> = indices
                .iter()
                .map(|&v| mesh.positions[v as usize])
                .collect();
            for c in corners.iter().flatten() {
                bin.extend(c.to_le_bytes());
            }
            views.push(json!({"buffer": 0, "byteOffset": start,
                              "byteLength": bin.len() - start}));
            accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5126,
                                  "count": indices.len(), "type": "VEC3",
                                  "min": bound(&corners, f32::min),
                                  "max": bound(&corners, f32::max)}));
            attributes = json!({"POSITION": accessors.len() - 1});
        } else {
            let component = [5123, 5125, 5121][g % 3];
            for &v in &indices {
                match component {
                    5121 => bin.push(v as u8),
                    5123 => bin.extend((v as u16).to_le_bytes()),
                    _ => bin.extend(v.to_le_bytes()),
                }
            }
            views.push(json!({"buffer": 0, "byteOffset": start,
                              "byteLength": bin.len() - start}));
            accessors.push(
                json!({"bufferView": views.len() - 1, "componentType": component,
                                  "count": indices.len(), "type": "SCALAR"}),
            );
            primitive["indices"] = json!(accessors.len() - 1);
        }
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        primitive["attributes"] = attributes;
        if let Some(m) = material {
            primitive["material"] = json!(m);
        }
        primitives.push(primitive);
    }
    let mut buffer = json!({"byteLength": bin.len()});
    if let Some(uri) = uri {
        buffer["uri"] = json!(uri);
    }
    let document = json!({
        "asset": {"version": "2.0", "generator": "vtq tests"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_transmission",
                           "KHR_materials_ior"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives}],
        "materials": gltf_materials(),
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [buffer],
    });
    (document, bin)
}

/// The per-axis minimum or maximum (`pick`) of `points`, as glTF's `POSITION` accessors
/// record them.
pub fn bound(points: &[[f32; 3]], pick: fn(f32, f32) -> f32) -> [f32; 3] {
    let mut out = points[0];
    for p in points {
        for (o, &c) in out.iter_mut().zip(p) {
            *o = pick(*o, c);
        }
    }
    out
}

/// The mesh as a `.gltf` text whose buffer is a base64 `data:` URI.
pub fn gltf_embedded(mesh: &Mesh) -> String {
    let (_, bin) = gltf(mesh, 12, None);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64_encode(&bin)
    );
    let (document, _) = gltf(mesh, 12, Some(uri));
    document.to_string()
}

/// `document` (with its buffer 0 the binary chunk) and `bin` as a GLB file.
pub fn glb(document: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = document.to_string().into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// Standard base64 with padding.
pub fn base64_encode(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let n = chunk
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &b)| n | u32::from(b) << (16 - 8 * i));
        for i in 0..=chunk.len() {
            out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
        }
        for _ in chunk.len()..3 {
            out.push('=');
        }
    }
    out
}

/// PLY encodings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyFormat {
    /// `ascii 1.0`.
    Ascii,
    /// `binary_little_endian 1.0`.
    LittleEndian,
    /// `binary_big_endian 1.0`.
    BigEndian,
}

/// The mesh's polygons (materials dropped) as a PLY file with per-vertex colours (`uchar red
/// green blue`, not used by vtq) and `double` z coordinates; `extra` adds an `edge` element of
/// two edges.
pub fn ply(mesh: &Mesh, format: PlyFormat, extra: bool) -> Vec<u8> {
    let faces: Vec<&Vec<u32>> = mesh.groups.iter().flat_map(|(_, f)| f).collect();
    let encoding = match format {
        PlyFormat::Ascii => "ascii",
        PlyFormat::LittleEndian => "binary_little_endian",
        PlyFormat::BigEndian => "binary_big_endian",
    };
    let mut out = format!(
        "ply\nformat {encoding} 1.0\ncomment written by the vtq tests\nelement vertex {}\n\
         property float x\nproperty float y\nproperty double z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar int vertex_indices\n",
        mesh.positions.len(),
        faces.len()
    );
    if extra {
        out.push_str("element edge 2\nproperty int vertex1\nproperty int vertex2\n");
    }
    out.push_str("end_header\n");
    let mut out = out.into_bytes();
    let big = format == PlyFormat::BigEndian;
    let put = |out: &mut Vec<u8>, le: &[u8]| {
        if big {
            out.extend(le.iter().rev());
        } else {
            out.extend(le);
        }
    };
    for p in &mesh.positions {
        if format == PlyFormat::Ascii {
            out.extend(format!("{} {} {} 200 100 50\n", p[0], p[1], p[2]).bytes());
        } else {
            put(&mut out, &p[0].to_le_bytes());
            put(&mut out, &p[1].to_le_bytes());
            put(&mut out, &f64::from(p[2]).to_le_bytes());
            out.extend([200, 100, 50]);
        }
    }
    for face in &faces {
        if format == PlyFormat::Ascii {
            let corners: Vec<String> = face.iter().map(u32::to_string).collect();
            out.extend(format!("{} {}\n", face.len(), corners.join(" ")).bytes());
        } else {
            out.push(face.len() as u8);
            for &v in face.iter() {
                put(&mut out, &(v as i32).to_le_bytes());
            }
        }
    }
    if extra {
        for (a, b) in [(0i32, 1i32), (1, 2)] {
            if format == PlyFormat::Ascii {
                out.extend(format!("{a} {b}\n").bytes());
            } else {
                put(&mut out, &a.to_le_bytes());
                put(&mut out, &b.to_le_bytes());
            }
        }
    }
    out
}

/// A `scene.toml` named `name` with a camera looking at the room.
pub fn manifest(name: &str) -> String {
    format!(
        "name = \"{name}\"\n[camera]\neye = [0, 1.5, 6]\nlook_at = [0, 1, 0]\nup = [0, 1, 0]\n\
         fov_y_deg = 45\n"
    )
}
