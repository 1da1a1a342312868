//! glTF (.gltf with a base64 or separate buffer, .glb) and PLY (ASCII, binary little- and
//! big-endian) scenes generated in code: they load the same triangles and materials as the same
//! mesh written as OBJ, render and simulate to identical images and statistics, place meshes
//! by their node hierarchy, take the first glTF camera, and report what they do not use.

mod common;
mod scene_writers;

use std::path::Path;

use glam::Vec3;
use scene_writers::{
    glb, gltf, gltf_embedded, manifest, obj, ply, room, temp_dir, write, Mesh, PlyFormat, MTL,
};
use serde_json::json;
use vtq_sim::model::bvh::HwBvh;
use vtq_sim::model::config::SimConfig;
use vtq_sim::model::gpu::stats::comparable_json;
use vtq_sim::model::gpu::{simulate, SimOptions};
use vtq_sim::model::scene::load::{load_scene_with_report, LoadedScene};
use vtq_sim::model::scene::Scene;
use vtq_sim::model::workload::pathtracer::render;

/// Load `path` as a scene spec, which must succeed.
fn load(path: &Path) -> LoadedScene {
    load_scene_with_report(path.to_str().expect("utf-8 temp path"))
        .unwrap_or_else(|e| panic!("{} does not load: {e}", path.display()))
}

/// A folder `dir/tag` holding `files` (name, bytes) and the room's `scene.toml`.
fn folder(dir: &Path, tag: &str, files: &[(&str, Vec<u8>)]) -> std::path::PathBuf {
    let folder = dir.join(tag);
    std::fs::create_dir_all(&folder).unwrap();
    for (name, bytes) in files {
        write(&folder, name, bytes);
    }
    write(&folder, "scene.toml", manifest("ROOM"));
    folder
}

/// The OBJ version of `mesh` (with the material library) in `dir/tag`.
fn obj_folder(dir: &Path, tag: &str, mesh: &Mesh) -> std::path::PathBuf {
    folder(
        dir,
        tag,
        &[
            ("room.obj", obj(mesh).into_bytes()),
            ("scene.mtl", MTL.as_bytes().to_vec()),
        ],
    )
}

/// Assert that two scenes hold the same geometry, materials, camera and sky.
fn assert_same_scene(a: &Scene, b: &Scene, what: &str) {
    assert_eq!(a.positions, b.positions, "{what}: positions");
    assert_eq!(a.triangles, b.triangles, "{what}: triangles");
    assert_eq!(a.tri_material, b.tri_material, "{what}: triangle materials");
    assert_eq!(a.materials, b.materials, "{what}: materials");
    assert_eq!(a.camera, b.camera, "{what}: camera");
    assert_eq!((&a.name, a.sky), (&b.name, b.sky), "{what}: name and sky");
}

/// The room as glTF with a base64 buffer, with a separate `.bin` (16-byte position stride)
/// and as GLB, each in its own folder.
fn gltf_folders(dir: &Path, mesh: &Mesh) -> Vec<(&'static str, std::path::PathBuf)> {
    let (separate, bin) = gltf(mesh, 16, Some("room%20data.bin".into()));
    let (binary, glb_bin) = gltf(mesh, 12, None);
    vec![
        (
            "embedded",
            folder(
                dir,
                "embedded",
                &[("room.gltf", gltf_embedded(mesh).into_bytes())],
            ),
        ),
        (
            "separate",
            folder(
                dir,
                "separate",
                &[
                    ("room.gltf", separate.to_string().into_bytes()),
                    ("room data.bin", bin),
                ],
            ),
        ),
        (
            "glb",
            folder(dir, "glb", &[("room.glb", glb(&binary, &glb_bin))]),
        ),
    ]
}

/// The room without materials as PLY in ASCII, binary little-endian (with an extra element)
/// and binary big-endian, each in its own folder.
fn ply_folders(dir: &Path, mesh: &Mesh) -> Vec<(&'static str, std::path::PathBuf)> {
    [
        ("ascii", PlyFormat::Ascii, false),
        ("little", PlyFormat::LittleEndian, true),
        ("big", PlyFormat::BigEndian, false),
    ]
    .into_iter()
    .map(|(tag, format, extra)| {
        let bytes = ply(mesh, format, extra);
        (tag, folder(dir, tag, &[("room.ply", bytes)]))
    })
    .collect()
}

#[test]
fn gltf_and_glb_load_the_triangles_and_materials_of_the_same_obj() {
    let dir = temp_dir("gltf-vs-obj");
    let mesh = room();
    let reference = load(&obj_folder(&dir, "obj", &mesh));
    assert_eq!(reference.scene.triangles.len(), 21);
    assert_eq!(reference.scene.materials.len(), 5, "default + 4");
    for (tag, path) in gltf_folders(&dir, &mesh) {
        let loaded = load(&path);
        assert_same_scene(&reference.scene, &loaded.scene, tag);
        // The glTF files use every extension they name and every attribute they hold.
        assert_eq!(loaded.report.ignored_line(), None, "{tag}");
        assert!(loaded.report.warnings(21).is_empty(), "{tag}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ply_loads_the_triangles_of_the_same_obj_in_every_encoding() {
    let dir = temp_dir("ply-vs-obj");
    let mesh = room().without_materials();
    let reference = load(&obj_folder(&dir, "obj", &mesh));
    for (tag, path) in ply_folders(&dir, &mesh) {
        let loaded = load(&path);
        assert_same_scene(&reference.scene, &loaded.scene, tag);
        let ignored = loaded.report.ignored_line().expect("colours are counted");
        assert!(
            ignored.starts_with(
                "ignored: in .ply files: vertex red x22, vertex green x22, vertex blue x22"
            ),
            "{tag}: {ignored}"
        );
        assert_eq!(
            ignored.contains("element edge x2"),
            tag == "little",
            "{tag}: {ignored}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn gltf_and_ply_scenes_render_and_simulate_like_obj() {
    let dir = temp_dir("render");
    let mesh = room();
    let cfg = SimConfig::load(
        None,
        &[
            "mode.kind=baseline",
            "gpu.sms=2",
            "width=16",
            "height=16",
            "memory.l1_bytes=4096",
            "memory.l2_bytes=16384",
            "hw.treelet_bytes=2048",
        ]
        .map(String::from),
    )
    .expect("valid test configuration");
    let run = |scene: &Scene| {
        let bvh = HwBvh::build(scene, &cfg.bvh_params()).expect("BVH builds");
        let image = render(scene, &bvh, &cfg.render_settings(), None)
            .expect("renders")
            .image;
        let sim = simulate(scene, &bvh, &cfg, SimOptions::default(), None).expect("simulates");
        assert_eq!(sim.image, image, "{}: the simulation's image", scene.name);
        (image, comparable_json(&sim.stats))
    };
    let reference = run(&load(&obj_folder(&dir, "obj", &mesh)).scene);
    assert!(
        reference.0.iter().any(|&c| c != Vec3::ZERO),
        "the camera sees the room"
    );
    for (tag, path) in gltf_folders(&dir, &mesh) {
        assert!(run(&load(&path).scene) == reference, "{tag}");
    }
    let grey = mesh.without_materials();
    let reference = run(&load(&obj_folder(&dir, "obj-grey", &grey)).scene);
    for (tag, path) in ply_folders(&dir, &grey) {
        assert!(run(&load(&path).scene) == reference, "{tag}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A glTF document of one triangle mesh and the given nodes, scenes and cameras.
fn one_triangle(nodes: serde_json::Value, scene_nodes: serde_json::Value) -> serde_json::Value {
    let mut bin = Vec::new();
    for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend(c.to_le_bytes());
    }
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": scene_nodes}],
        "nodes": nodes,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.75, "znear": 0.1}},
                    {"type": "orthographic",
                     "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": format!(
            "data:application/gltf-buffer;base64,{}", scene_writers::base64_encode(&bin))}],
    })
}

#[test]
fn node_transforms_place_meshes_in_world_space() {
    let dir = temp_dir("nodes");
    // Node 0 moves and scales its children; node 1 adds a translation, node 2 a matrix (column
    // major: translation last); node 3 is a second root without a transform.
    let nodes = json!([
        {"translation": [10, 0, 0], "scale": [2, 2, 2], "children": [1, 2]},
        {"mesh": 0, "translation": [0, 0, -1]},
        {"mesh": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,5,0,1]},
        {"mesh": 0},
        {"camera": 0, "translation": [0, 0, 20]},
    ]);
    let document = one_triangle(nodes, json!([0, 3, 4]));
    let path = write(&dir, "nodes.gltf", document.to_string());
    let scene = load(&path).scene;
    let corners: Vec<[Vec3; 3]> = (0..scene.triangles.len())
        .map(|i| scene.triangle(i))
        .collect();
    let v = Vec3::new;
    assert_eq!(
        corners,
        [
            [v(10.0, 0.0, -2.0), v(12.0, 0.0, -2.0), v(10.0, 2.0, -2.0)],
            [v(10.0, 10.0, 0.0), v(12.0, 10.0, 0.0), v(10.0, 12.0, 0.0)],
            [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)],
        ],
        "depth first, each mesh instance by its world transform"
    );
    // A node reached twice (a cycle) is an error, not a hang.
    let cyclic = one_triangle(json!([{"mesh": 0, "children": [0]}]), json!([0]));
    let path = write(&dir, "cycle.gltf", cyclic.to_string());
    let err = load_scene_with_report(path.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("cycle.gltf") && err.contains("node 0 is reached twice"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_first_perspective_gltf_camera_is_the_scene_camera() {
    let dir = temp_dir("camera");
    // The orthographic camera (node 1) comes first in depth-first order and is counted; the
    // perspective one sits under a translated rig, turned 90 degrees about +Y.
    let half = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = json!([
        {"mesh": 0},
        {"camera": 1},
        {"translation": [0, 1, 0], "children": [3]},
        {"camera": 0, "translation": [0, 0.5, 6], "rotation": [0, half, 0, half]},
        {"camera": 0, "translation": [9, 9, 9]},
    ]);
    let document = one_triangle(nodes, json!([0, 1, 2, 4]));
    let single = write(&dir, "cam.gltf", document.to_string());
    let loaded = load(&single);
    let camera = loaded.scene.camera;
    assert_eq!(camera.eye, Vec3::new(0.0, 1.5, 6.0));
    let view = camera.look_at - camera.eye;
    assert!(
        (view - Vec3::NEG_X).length() < 1e-6,
        "-Z turned to -X: {view}"
    );
    assert!((camera.up - Vec3::Y).length() < 1e-6, "{}", camera.up);
    assert_eq!(camera.fov_y_deg, 0.75f32.to_degrees());
    let ignored = loaded.report.ignored_line().unwrap();
    assert!(
        ignored.contains("camera (orthographic) x1")
            && ignored.contains("camera (not the first) x1"),
        "{ignored}"
    );

    // In a folder the glTF camera wins over scene.toml's, which is reported as not used; a
    // scene.toml without [camera] is fine when a glTF file has a camera.
    let with_manifest = folder(
        &dir,
        "with",
        &[("cam.gltf", document.to_string().into_bytes())],
    );
    let loaded = load(&with_manifest);
    assert_eq!(loaded.scene.camera, camera);
    assert_eq!(loaded.scene.name, "ROOM");
    let warnings = loaded.report.warnings(1);
    assert!(
        warnings.len() == 1
            && warnings[0].contains("[camera] of")
            && warnings[0].contains("cam.gltf"),
        "{warnings:?}"
    );
    let no_camera_key = dir.join("no_key");
    std::fs::create_dir_all(&no_camera_key).unwrap();
    write(&no_camera_key, "cam.gltf", document.to_string());
    write(&no_camera_key, "scene.toml", "name = \"CAM\"\n");
    assert_eq!(load(&no_camera_key).scene.camera, camera);

    // Without a glTF camera: scene.toml's camera, else one framing the bounds (as for OBJ and
    // PLY files), reported; a scene.toml without a [camera] is still an error.
    let no_camera = one_triangle(json!([{"mesh": 0}]), json!([0]));
    let with_manifest = folder(
        &dir,
        "nocam",
        &[("m.gltf", no_camera.to_string().into_bytes())],
    );
    assert_eq!(
        load(&with_manifest).scene.camera.eye,
        Vec3::new(0.0, 1.5, 6.0)
    );
    let bare = write(&dir, "bare.gltf", no_camera.to_string());
    let framed = load_scene_with_report(bare.to_str().unwrap()).unwrap();
    let bare_folder = dir.join("bare");
    std::fs::create_dir_all(&bare_folder).unwrap();
    write(&bare_folder, "m.gltf", no_camera.to_string());
    let framed_folder = load_scene_with_report(bare_folder.to_str().unwrap()).unwrap();
    for loaded in [&framed, &framed_folder] {
        assert!(loaded.report.framed_camera);
        assert!(loaded.report.camera_line().unwrap().contains("frames"));
        // The camera looks at the mesh: the centre of its bounds is straight ahead.
        let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for &p in &loaded.scene.positions {
            (min, max) = (min.min(p), max.max(p));
        }
        let cam = &loaded.scene.camera;
        let to_centre = ((min + max) * 0.5 - cam.eye).normalize();
        let view = (cam.look_at - cam.eye).normalize();
        assert!(to_centre.dot(view) > 0.999, "{cam:?}");
    }
    assert_eq!(framed.scene.camera, framed_folder.scene.camera);
    // A glTF camera is not reported as framed.
    assert!(!load(&with_manifest).report.framed_camera);
    write(&bare_folder, "scene.toml", "name = \"X\"\n");
    let err = load_scene_with_report(bare_folder.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("scene.toml") && err.contains("no [camera]"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unused_gltf_content_is_counted() {
    let dir = temp_dir("ignored");
    let mut document = one_triangle(json!([{"mesh": 0}, {"camera": 0}]), json!([0, 1]));
    // A textured, blended material; a normal attribute; a LINES primitive; an extension vtq
    // does not read; an animation-free second scene.
    document["materials"] = json!([{
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                                 "baseColorFactor": [1, 1, 1, 0.5]},
        "normalTexture": {"index": 0}, "alphaMode": "BLEND"}]);
    document["textures"] = json!([{"source": 0}]);
    document["images"] = json!([{"uri": "wood.png"}]);
    document["extensionsUsed"] = json!(["KHR_texture_transform"]);
    document["scenes"] = json!([{"nodes": [0, 1]}, {"nodes": [0]}]);
    document["meshes"] = json!([{"primitives": [
        {"attributes": {"POSITION": 0, "NORMAL": 0}, "material": 0},
        {"attributes": {"POSITION": 0}, "mode": 1},
    ]}]);
    let path = write(&dir, "ignored.gltf", document.to_string());
    let loaded = load(&path);
    assert_eq!(loaded.scene.triangles.len(), 1);
    assert_eq!(
        loaded.report.ignored_line().unwrap(),
        "ignored: in glTF files: extension KHR_texture_transform x1, baseColorTexture x1, \
         normalTexture x1, alphaMode BLEND x1, baseColorFactor alpha x1, scene (not read) x1, \
         attribute NORMAL x1, mode LINES x1"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
