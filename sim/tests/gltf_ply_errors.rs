//! Malformed glTF, GLB and PLY files: each is one error naming the file and the problem, never
//! a panic, and a non-finite PLY vertex leaves out its triangles as in OBJ.

mod common;
mod scene_writers;

use std::path::Path;

use scene_writers::{glb, gltf, manifest, ply, room, temp_dir, write, PlyFormat};
use serde_json::{json, Value};
use vtq_sim::model::scene::load::load_scene_with_report;

/// The one-line error of loading `path`, which must fail and name the file.
fn load_err(path: &Path) -> String {
    match load_scene_with_report(path.to_str().expect("utf-8 temp path")) {
        Ok(loaded) => panic!(
            "{} loaded ({} triangles) but should fail",
            path.display(),
            loaded.scene.triangles.len()
        ),
        Err(e) => {
            let msg = e.to_string();
            let name = path.file_name().unwrap().to_string_lossy();
            assert!(msg.contains(&*name), "names the file: {msg}");
            assert!(!msg.contains('\n'), "one line: {msg}");
            msg
        }
    }
}

/// The room as a glTF document whose buffer is `room.bin`, edited by `edit`.
fn edited(edit: impl Fn(&mut Value)) -> (Value, Vec<u8>) {
    let (mut document, bin) = gltf(&room(), 12, Some("room.bin".into()));
    edit(&mut document);
    (document, bin)
}

#[test]
fn malformed_gltf_files_are_errors_naming_file_and_problem() {
    let dir = temp_dir("gltf-errors");
    let (_, bin) = edited(|_| {});
    write(&dir, "room.bin", &bin);
    let cases: Vec<(&str, Value, &str)> = vec![
        (
            "accessor_index",
            edited(|d| d["meshes"][0]["primitives"][0]["indices"] = json!(99)).0,
            "Index out of bounds",
        ),
        (
            "required_extension",
            edited(|d| d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])).0,
            "KHR_draco_mesh_compression",
        ),
        (
            "short_buffer",
            edited(|d| d["buffers"][0]["byteLength"] = json!(100_000)).0,
            "byteLength",
        ),
        (
            "missing_bin",
            edited(|d| d["buffers"][0]["uri"] = json!("nowhere.bin")).0,
            "'nowhere.bin' does not exist",
        ),
        (
            "http_uri",
            edited(|d| d["buffers"][0]["uri"] = json!("https://example.com/room.bin")).0,
            "scheme 'https:'",
        ),
        (
            "view_past_buffer",
            edited(|d| d["bufferViews"][1]["byteOffset"] = json!(1_000_000)).0,
            "runs past",
        ),
        (
            "accessor_past_view",
            edited(|d| d["accessors"][0]["count"] = json!(1000)).0,
            "run past",
        ),
        (
            "index_range",
            edited(|d| d["accessors"][0]["count"] = json!(3)).0,
            "out of range (3 positions)",
        ),
        (
            "quantized_positions",
            edited(|d| {
                d["accessors"][0]["componentType"] = json!(5123);
                d["accessors"][0]["normalized"] = json!(true);
            })
            .0,
            "POSITION",
        ),
        (
            "position_accessor",
            edited(|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99)).0,
            "accessor 99 does not exist",
        ),
        (
            "camera_type",
            edited(|d| {
                d["cameras"] =
                    json!([{"type": "orthographic", "perspective": {"yfov": 1, "znear": 0.1}}]);
                d["nodes"][0]["camera"] = json!(0);
            })
            .0,
            "no \"orthographic\" object",
        ),
        (
            "cycle",
            edited(|d| d["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}])).0,
            "reached twice",
        ),
        (
            "no_scene",
            edited(|d| {
                d.as_object_mut().unwrap().remove("scene");
                d["scenes"] = json!([]);
            })
            .0,
            "no scene",
        ),
        (
            "huge_factor",
            // Each number fits f32, their product does not.
            edited(|d| {
                d["materials"][1]["emissiveFactor"] = json!([10, 0, 0]);
                d["materials"][1]["extensions"]["KHR_materials_emissive_strength"]
                    ["emissiveStrength"] = json!(1e38);
            })
            .0,
            "not a finite number",
        ),
    ];
    for (tag, document, needle) in cases {
        let path = write(&dir, &format!("{tag}.gltf"), document.to_string());
        let msg = load_err(&path);
        assert!(msg.contains(needle), "{tag}: {msg}");
    }
    for (tag, text, needle) in [
        ("not_json", "{\"asset\": ", "invalid glTF JSON"),
        ("no_asset", "{}", "asset"),
    ] {
        let path = write(&dir, &format!("{tag}.gltf"), text);
        let msg = load_err(&path);
        assert!(msg.contains(needle), "{tag}: {msg}");
    }
    let (document, bin) = gltf(&room(), 12, None);
    let good = glb(&document, &bin);
    let mut short_header = good.clone();
    short_header[8..12].copy_from_slice(&4u32.to_le_bytes());
    let mut long_chunk = good.clone();
    long_chunk[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    // The JSON chunk alone: buffer 0 names the binary chunk, which is not there.
    let mut without_bin = glb(&document, &[]);
    without_bin.truncate(without_bin.len() - 8);
    let total = without_bin.len() as u32;
    without_bin[8..12].copy_from_slice(&total.to_le_bytes());
    for (tag, bytes, needle) in [
        ("short_header", short_header, "less than the header"),
        ("truncated", good[..10].to_vec(), "header"),
        ("long_chunk", long_chunk, "invalid GLB"),
        ("without_bin", without_bin, "binary chunk"),
    ] {
        let path = write(&dir, &format!("{tag}.glb"), bytes);
        let msg = load_err(&path);
        assert!(msg.contains(needle), "{tag}: {msg}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_incomplete_last_triangle_is_counted_not_refused() {
    let dir = temp_dir("incomplete");
    let (document, bin) = edited(|d| d["accessors"][1]["count"] = json!(5));
    write(&dir, "room.bin", &bin);
    write(&dir, "incomplete.gltf", document.to_string());
    write(&dir, "scene.toml", manifest("ROOM"));
    let loaded = load_scene_with_report(dir.to_str().unwrap()).expect("loads");
    assert_eq!(
        loaded.scene.triangles.len(),
        20,
        "the wall's second triangle is cut"
    );
    let ignored = loaded.report.ignored_line().unwrap();
    assert!(ignored.contains("incomplete triangle x1"), "{ignored}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn malformed_ply_files_are_errors_naming_file_and_problem() {
    let dir = temp_dir("ply-errors");
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                  end_header\n";
    let vertices = "0 0 0\n1 0 0\n0 1 0\n";
    for (tag, text, needle) in [
        ("not_ply", "solid cube\n".to_string(), "invalid PLY header"),
        (
            "point_cloud",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
             property float z\nend_header\n0 0 0\n"
                .to_string(),
            "point cloud",
        ),
        (
            "no_z",
            header.replace("property float z\n", "") + "0 0\n1 0\n0 1\n3 0 1 2\n",
            "no 'z' property",
        ),
        (
            "index_range",
            format!("{header}{vertices}3 0 1 7\n"),
            "vertex index 7 is out of range (3 vertices)",
        ),
        (
            "negative",
            format!("{header}{vertices}3 0 -1 2\n"),
            "vertex index -1 is negative",
        ),
        (
            "two_corners",
            format!("{header}{vertices}2 0 1\n"),
            "face 0 has 2 vertices",
        ),
        ("truncated", format!("{header}{vertices}"), "face data"),
        (
            "not_a_number",
            format!("{header}0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"),
            "vertex data",
        ),
        (
            "float_indices",
            header.replace("uchar int", "uchar float") + vertices + "3 0 1 2\n",
            "floating-point",
        ),
    ] {
        let path = write(&dir, &format!("{tag}.ply"), text);
        let msg = load_err(&path);
        assert!(msg.contains(needle), "{tag}: {msg}");
    }
    for format in [PlyFormat::LittleEndian, PlyFormat::BigEndian] {
        let good = ply(&room(), format, true);
        let path = write(&dir, "cut.ply", &good[..good.len() - 5]);
        let msg = load_err(&path);
        assert!(msg.contains("edge data"), "{format:?}: {msg}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn non_finite_ply_vertices_leave_out_their_triangles() {
    let dir = temp_dir("ply-nonfinite");
    let text = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
                property double z\nelement face 2\nproperty list uchar uint vertex_index\n\
                end_header\n0 0 0\n1 0 0\n0 1 0\n1e39 0 0\n0 0 1e300\n3 0 1 2\n4 0 3 4 1\n";
    let path = write(&dir, "holes.ply", text);
    let loaded = load_scene_with_report(path.to_str().unwrap()).expect("loads");
    assert_eq!(loaded.scene.triangles.len(), 1);
    assert_eq!(
        (
            loaded.report.nonfinite_vertices,
            loaded.report.nonfinite_triangles
        ),
        (2, 2)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
