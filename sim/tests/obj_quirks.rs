//! What real exporters write (Blender, 3ds Max, ZBrush, ...), each case generated here: empty
//! `usemtl`, unnamed groups, smoothing groups, a UTF-8 byte-order mark, CRLF, `\` continuations,
//! negative indices, vertex colours and `w`, large polygons, and statements vtq does not use
//! (ignored and counted); non-finite vertices (triangles left out and counted); broken data (an
//! error naming the file and line).

mod common;

use std::path::{Path, PathBuf};

use glam::Vec3;
use vtq_sim::model::scene::load::{load_scene_with_report, LoadedScene};
use vtq_sim::model::scene::report::LoadReport;
use vtq_sim::{Material, Scene};

/// A fresh, empty temporary folder unique to this process and `tag`.
fn temp_dir(tag: &str) -> PathBuf {
    common::fresh_dir(&format!("obj-quirks-{tag}"))
}

/// Write `bytes` to `dir/name` and return the path.
fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write test file");
    path
}

/// Load `path` with its report.
fn load(path: &Path) -> LoadedScene {
    load_scene_with_report(path.to_str().expect("utf-8 path"))
        .unwrap_or_else(|e| panic!("{} should load: {e}", path.display()))
}

/// The error of loading `path`, which must fail.
fn load_err(path: &Path) -> String {
    match load_scene_with_report(path.to_str().expect("utf-8 path")) {
        Ok(l) => panic!(
            "{} loaded ({} triangles) but should fail",
            path.display(),
            l.scene.triangles.len()
        ),
        Err(e) => e.to_string(),
    }
}

/// Every triangle's corner positions, in id order.
fn corners(scene: &Scene) -> Vec<[Vec3; 3]> {
    (0..scene.triangles.len())
        .map(|i| scene.triangle(i))
        .collect()
}

/// The material of every triangle, in id order.
fn materials(scene: &Scene) -> Vec<Material> {
    (0..scene.triangles.len())
        .map(|i| *scene.material_of(i as u32))
        .collect()
}

/// A Blender-style scene: a library with two materials and an OBJ using them, an empty
/// `usemtl`, unnamed `o`/`g`, smoothing groups, and a quad.
const BLENDER_MTL: &str = "# Blender MTL File: 'None'\n# Material Count: 2\n\n\
    newmtl red\nNs 250.000000\nKa 1.000000 1.000000 1.000000\nKd 0.800000 0.000000 0.000000\n\
    Ks 0.500000 0.500000 0.500000\nKe 0.000000 0.000000 0.000000\nNi 1.450000\nd 1.000000\n\
    illum 2\nmap_Kd red.png\n\n\
    newmtl lamp\nKd 0 0 0\nKe 2 2 2\nd 1.0\nillum 2\n";

const BLENDER_OBJ: &str = "# Blender v2.79 (sub 0) OBJ File: ''\n# www.blender.org\n\
    mtllib scene.mtl\no\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
    usemtl red\ns off\nf 1/1/1 2/1/1 3/1/1 4/1/1\n\
    g\nusemtl \ns 1\nf 1//1 2//1 3//1\n\
    o Lamp\nusemtl lamp\nf 1 3 4\n";

#[test]
fn blender_export_with_empty_usemtl_and_unnamed_groups() {
    let dir = temp_dir("blender");
    write(&dir, "scene.mtl", BLENDER_MTL);
    let obj = write(&dir, "scene.obj", BLENDER_OBJ);
    let LoadedScene { scene, report } = load(&obj);
    let red = Material::Lambertian {
        albedo: Vec3::new(0.8, 0.0, 0.0),
    };
    let lamp = Material::Light {
        emit: Vec3::splat(2.0),
    };
    // The quad (two triangles) is red, the face after the empty usemtl is the default grey.
    assert_eq!(
        materials(&scene),
        [red, red, Material::DEFAULT, lamp],
        "an empty usemtl selects the default material"
    );
    assert_eq!(report.ignored.get("o"), 2);
    assert_eq!(report.ignored.get("g"), 1);
    assert_eq!(report.ignored.get("s"), 2);
    assert_eq!(report.ignored.get("vt"), 1);
    assert_eq!(report.ignored.get("vn"), 1);
    assert_eq!(report.mtl_ignored.get("Ka"), 1);
    assert_eq!(report.mtl_ignored.get("map_Kd"), 1);
    assert_eq!(
        report.ignored_line().unwrap(),
        "ignored: o x2, vt x1, vn x1, s x2, g x1; in .mtl files: Ka x1, map_Kd x1"
    );
    assert!(report.warnings(scene.triangles.len()).is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_byte_order_mark_keeps_the_first_vertex() {
    let dir = temp_dir("bom");
    // With the mark read as part of the first word, `v 0 0 0` would be skipped and `f 1 2 3`
    // would silently use vertices 2, 3 and 4.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n";
    let plain = load(&write(&dir, "plain.obj", text));
    let bom = load(&write(
        &dir,
        "bom.obj",
        [b"\xEF\xBB\xBF", text.as_bytes()].concat(),
    ));
    assert_eq!(
        corners(&bom.scene),
        [[Vec3::ZERO, Vec3::X, Vec3::Y]],
        "all four vertices are loaded, so index 1 is the first"
    );
    assert_eq!(bom.scene.positions, plain.scene.positions);
    assert!(bom.report.ignored.is_empty(), "{:?}", bom.report);
    // A library with a mark loads its first material too.
    write(
        &dir,
        "bom.mtl",
        [b"\xEF\xBB\xBF" as &[u8], b"newmtl m\nKd 0 0 1\n"].concat(),
    );
    let with_mtl = load(&write(
        &dir,
        "bom_mtl.obj",
        [
            b"\xEF\xBB\xBF" as &[u8],
            b"mtllib bom.mtl\nusemtl m\n",
            text.as_bytes(),
        ]
        .concat(),
    ));
    assert_eq!(
        materials(&with_mtl.scene),
        [Material::Lambertian { albedo: Vec3::Z }]
    );
    // UTF-16 is refused by name, not misread.
    let utf16: Vec<u8> = [0xFF, 0xFE]
        .into_iter()
        .chain(text.encode_utf16().flat_map(u16::to_le_bytes))
        .collect();
    let err = load_err(&write(&dir, "utf16.obj", utf16));
    assert!(err.contains("utf16.obj") && err.contains("UTF-16"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn crlf_files_load_like_lf_files() {
    let dir = temp_dir("crlf");
    let crlf = |s: &str| s.replace('\n', "\r\n");
    write(&dir, "scene.mtl", BLENDER_MTL);
    let lf = load(&write(&dir, "lf.obj", BLENDER_OBJ));
    std::fs::create_dir_all(dir.join("crlf")).unwrap();
    // The library name must not keep the `\r`, nor the material names.
    write(&dir.join("crlf"), "scene.mtl", crlf(BLENDER_MTL));
    let crlf_scene = load(&write(&dir.join("crlf"), "lf.obj", crlf(BLENDER_OBJ)));
    assert_eq!(crlf_scene.scene.positions, lf.scene.positions);
    assert_eq!(crlf_scene.scene.triangles, lf.scene.triangles);
    assert_eq!(crlf_scene.scene.tri_material, lf.scene.tri_material);
    assert_eq!(crlf_scene.scene.materials, lf.scene.materials);
    assert_eq!(crlf_scene.report, lf.report);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn backslash_continues_a_line() {
    let dir = temp_dir("continuation");
    // The error on the last face names its line (the continued face took lines 6-8).
    let err = load_err(&write(
        &dir,
        "cont.obj",
        "v 0 \\\n  0 0\nv 1 0 0\r\nv 1 1 0\nv 0 1 0\nf 1 2 \\\r\n 3 \\\n4\nf 1 2 bad\n",
    ));
    assert!(err.contains("line 9"), "{err}");
    let scene = load(&write(
        &dir,
        "cont_ok.obj",
        "v 0 \\\n  0 0\nv 1 0 0\r\nv 1 1 0\nv 0 1 0\nf 1 2 \\\r\n 3 \\\n4\n",
    ))
    .scene;
    assert_eq!(
        corners(&scene),
        [
            [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)],
            [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        ]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn negative_indices_count_back_in_every_slot() {
    let dir = temp_dir("negative");
    let scene = load(&write(
        &dir,
        "neg.obj",
        "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n\
         f -3/-3/-1 -2/-2/-1 -1/-1/-1\nv 0 0 1\nf -4 -3 -1\n",
    ))
    .scene;
    assert_eq!(
        corners(&scene),
        [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::ZERO, Vec3::X, Vec3::Z]
        ]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn vertex_colours_and_w_are_accepted() {
    let dir = temp_dir("colours");
    // Coloured and plain vertices may be mixed; w divides the position.
    let LoadedScene { scene, report } = load(&write(
        &dir,
        "colours.obj",
        "v 0 0 0 1.0 0.5 0.25\nv 2 0 0 2\nv 0 1 0\nv 0 0 1 0 0 0\nf 1 2 3\nf 1 2 4\n",
    ));
    assert_eq!(
        corners(&scene),
        [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::ZERO, Vec3::X, Vec3::Z]
        ]
    );
    assert_eq!(report.ignored.get("v rgb"), 2, "colours are counted");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn polygons_of_any_size_become_fans() {
    let dir = temp_dir("ngon");
    let n = 40;
    let mut text = String::new();
    for i in 0..n {
        let a = i as f32 / n as f32 * std::f32::consts::TAU;
        text.push_str(&format!("v {} {} 0\n", a.cos(), a.sin()));
    }
    text.push('f');
    for i in 1..=n {
        text.push_str(&format!(" {i}"));
    }
    text.push('\n');
    let scene = load(&write(&dir, "ngon.obj", &text)).scene;
    assert_eq!(scene.triangles.len(), n - 2);
    for (k, tri) in scene.triangles.iter().enumerate() {
        assert_eq!(*tri, [0, k as u32 + 1, k as u32 + 2], "fan triangle {k}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unused_statements_are_ignored_and_counted() {
    let dir = temp_dir("ignored");
    write(
        &dir,
        "all.mtl",
        "newmtl glass\nKa 0 0 0\nKd 1 1 1\nTr 0.9\nNi 1.5\nTf 1 1 1\nmap_Kd a.png\n\
         map_Bump -bm 1 b.png\nbump c.png\ndisp d.png\nrefl -type sphere e.png\nPr 0.3\n\
         Pc 0\nPcr 0\naniso 0\nnewmtl brushed\nKd 0.5 0.4 0.3\nPm 1\nPr 0.25\nmap_Kd f.png\n",
    );
    let mut text = String::from("mtllib all.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n");
    let statements = [
        ("l", "l 1 2 3 4", 12),
        ("p", "p 1 2", 2),
        ("vp", "vp 0.5 0.5", 3),
        ("cstype", "cstype bspline", 1),
        ("deg", "deg 3", 1),
        ("curv2", "curv2 1 2", 1),
        ("mg", "mg 1 0.5", 1),
        ("lod", "lod 1", 1),
        ("usemap", "usemap off", 1),
        ("o", "o", 1),
        ("g", "g a b", 1),
        ("s", "s off", 1),
    ];
    for (_, line, n) in statements {
        for _ in 0..n {
            text.push_str(line);
            text.push('\n');
        }
    }
    text.push_str("usemtl glass\nf 1 2 3\nusemtl brushed\nf 2 4 3\n");
    let LoadedScene { scene, report } = load(&write(&dir, "all.obj", &text));
    assert_eq!(
        scene.triangles.len(),
        2,
        "polylines and points are not surfaces"
    );
    for (keyword, _, n) in statements {
        assert_eq!(report.ignored.get(keyword), n, "{keyword}");
    }
    for (keyword, n) in [
        ("Ka", 1),
        ("Tf", 1),
        ("map_Kd", 2),
        ("map_Bump", 1),
        ("bump", 1),
        ("disp", 1),
        ("refl", 1),
        ("Pc", 1),
        ("Pcr", 1),
        ("aniso", 1),
    ] {
        assert_eq!(report.mtl_ignored.get(keyword), n, "{keyword}");
    }
    // Tr, Pr and Pm are read: Tr 0.9 with Ni makes glass; Pm 1 makes metal with fuzz Pr.
    assert_eq!(
        materials(&scene),
        [
            Material::Dielectric { ior: 1.5 },
            Material::Metal {
                albedo: Vec3::new(0.5, 0.4, 0.3),
                fuzz: 0.25
            }
        ]
    );
    let line = report.ignored_line().unwrap();
    assert!(
        line.starts_with("ignored: l x12, p x2, vp x3, cstype x1,")
            && line.contains("; in .mtl files: Ka x1, Tf x1, map_Kd x2, map_Bump x1, bump x1,"),
        "{line}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn non_finite_vertices_leave_out_their_triangles_and_are_counted() {
    let dir = temp_dir("nonfinite");
    let LoadedScene { scene, report } = load(&write(
        &dir,
        "holes.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nv 0 inf 0\nv 1e39 0 0\nv 1 1 1 0\nv -inf 0 0\n\
         f 1 2 3\nf 1 2 4\nf 1 5 3\nf 6 2 3\nf 1 7 2\nf 2 3 1\nf 1 2 3 4\n",
    ));
    // f 1 2 3 4 is two triangles: (1 2 3) kept, (1 3 4) left out.
    assert_eq!(
        corners(&scene),
        [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::X, Vec3::Y, Vec3::ZERO],
            [Vec3::ZERO, Vec3::X, Vec3::Y],
        ]
    );
    assert_eq!(
        scene.positions.len(),
        3,
        "non-finite vertices are not stored"
    );
    assert_eq!(report.nonfinite_vertices, 5);
    assert_eq!(report.nonfinite_triangles, 5);
    assert_eq!(
        report.left_out_line().unwrap(),
        "left out: 5 triangles using 5 non-finite vertices (nan, inf or w = 0)"
    );
    // A manifest counts the triangles in the files: loaded plus left out.
    let folder = dir.join("folder");
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::copy(dir.join("holes.obj"), folder.join("holes.obj")).unwrap();
    let manifest = |n: u32| {
        format!(
            "triangles = {n}\n[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\n\
             fov_y_deg = 40\n"
        )
    };
    write(&folder, "scene.toml", manifest(8));
    assert_eq!(load(&folder).report.manifest_mismatch, None);
    write(&folder, "scene.toml", manifest(3));
    let report = load(&folder).report;
    assert_eq!(
        report.manifest_mismatch,
        Some((folder.join("scene.toml"), 3))
    );
    let warnings = report.warnings(3);
    assert!(
        warnings[0].ends_with("says 3 triangles but the files hold 8 (3 loaded, 5 left out)"),
        "{warnings:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_libraries_and_undefined_materials_are_reported() {
    let dir = temp_dir("missing");
    write(&dir, "a b.mtl", "newmtl spaced\nKd 0 1 0\n");
    write(&dir, "two.mtl", "newmtl second\nKd 0 0 1\n");
    let LoadedScene { scene, report } = load(&write(
        &dir,
        "m.obj",
        "mtllib a b.mtl\nmtllib two.mtl gone.mtl\nmtllib absent.mtl\nmtllib absent.mtl\n\
         v 0 0 0\nv 1 0 0\nv 0 1 0\n\
         usemtl spaced\nf 1 2 3\nusemtl second\nf 1 2 3\nusemtl nowhere\nf 1 2 3\n",
    ));
    assert_eq!(
        materials(&scene),
        [
            Material::Lambertian { albedo: Vec3::Y },
            Material::Lambertian { albedo: Vec3::Z },
            Material::DEFAULT
        ],
        "a name with a blank is one file; several names are several files"
    );
    assert_eq!(
        report.missing_mtl,
        [dir.join("gone.mtl"), dir.join("absent.mtl")]
    );
    assert_eq!(report.undefined_materials, ["nowhere"]);
    let warnings = report.warnings(3);
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0].starts_with("2 material libraries not found"));
    assert!(warnings[1].contains("(first: 'nowhere')"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn broken_data_is_an_error_naming_file_and_line() {
    let dir = temp_dir("broken");
    for (name, text, needle) in [
        (
            "range.obj",
            "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 4\r\n",
            "line 4: vertex index 4 is out of range (3 defined so far",
        ),
        (
            "back.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
            "line 4: vertex index -4 is out of range",
        ),
        (
            "few.obj",
            "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
            "line 2: a vertex needs x y z, x y z w or x y z r g b; found 2 numbers",
        ),
        (
            "word.obj",
            "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n",
            "line 2: 'zero' is not a number (vertex coordinate)",
        ),
        (
            "index.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n",
            "line 4: 'x' in 'x' is not a vertex index",
        ),
        (
            "huge.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 18446744073709551617\n",
            "line 4: '18446744073709551617' in '18446744073709551617' is not a vertex index",
        ),
        (
            "two.obj",
            "v 0 0 0\nv 1 0 0\nf 1 2\n",
            "line 3: a face needs at least 3 vertices, found 2",
        ),
        (
            "vt.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
            "line 5: texture coordinate index 2 is out of range",
        ),
        (
            "garbage.obj",
            "v 0 0 0\n\u{1}\u{2}binary\n",
            "line 2: '\u{1}\u{2}binary' is not an OBJ statement",
        ),
        (
            "continued.obj",
            "v 0 0 0\nv 1 \\\n 0 0\nv 0 \\\n zero 0\n",
            "line 4: 'zero' is not a number",
        ),
    ] {
        let path = write(&dir, name, text);
        let err = load_err(&path);
        assert!(
            err.contains(path.to_str().unwrap()) && err.contains(needle),
            "{name}: {err}"
        );
        assert!(!err.contains('\n'), "one line: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn builtin_scenes_have_an_empty_report() {
    let loaded = load_scene_with_report("cornell").expect("cornell");
    assert_eq!(loaded.report, LoadReport::default());
    assert!(loaded.report.ignored_line().is_none() && loaded.report.left_out_line().is_none());
}

#[test]
fn huge_finite_coordinates_still_get_a_default_camera() {
    // Found by `vtq fuzz`: a vertex at 1e30 made the framing camera's distance overflow, so a
    // valid file failed with "camera: eye, look_at and up must be finite".
    let dir = temp_dir("huge");
    let scene = load(&write(
        &dir,
        "huge.obj",
        "v -1e30 0 0\nv 1e30 0 0\nv 0 3e37 -2e37\nf 1 2 3\n",
    ))
    .scene;
    assert!(scene.camera.check().is_ok(), "{:?}", scene.camera);
    assert_eq!(scene.camera.look_at, Vec3::new(0.0, 1.5e37, -1e37));
    // Ordinary bounds are framed exactly as before.
    let small = vtq_sim::Camera::framing(Vec3::ZERO, Vec3::splat(2.0));
    assert_eq!(small.look_at, Vec3::ONE);
    assert_eq!(
        small.eye,
        Vec3::new(1.0, 1.0, 1.0 + 3.0f32.sqrt() / 22.5f32.to_radians().sin())
    );
    let _ = std::fs::remove_dir_all(&dir);
}
