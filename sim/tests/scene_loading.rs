//! Scene loading: built-in scenes, OBJ triangulation and ids, MTL material mapping, scene
//! folders and manifests, error messages, and the real scenes in `../shared/scenes`.

mod common;

use std::path::{Path, PathBuf};

use glam::Vec3;
use vtq_sim::model::scene::builtin::{cornell, wknd};
use vtq_sim::model::scene::load::{list_scenes, load_scene, CountSource, SceneKind};
use vtq_sim::model::scene::manifest::Manifest;
use vtq_sim::{Material, Scene, SceneError};

/// A fresh, empty temporary folder unique to this process and `tag`.
fn temp_dir(tag: &str) -> PathBuf {
    common::fresh_dir(&format!("scene-loading-{tag}"))
}

/// Write `text` to `dir/name` and return the path.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write test file");
    path
}

/// Load `path` as a scene spec.
fn load(path: &Path) -> Result<Scene, SceneError> {
    load_scene(path.to_str().expect("utf-8 temp path"))
}

/// The error message of loading `path`, which must fail.
fn load_err(path: &Path) -> String {
    match load(path) {
        Ok(scene) => panic!(
            "{} loaded ({} triangles) but should fail",
            path.display(),
            scene.triangles.len()
        ),
        Err(e) => e.to_string(),
    }
}

/// The shared scenes folder as `../shared/scenes` from the workspace root, if present.
fn shared_scenes() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = root.join("../shared/scenes");
    dir.is_dir().then_some(dir)
}

#[test]
fn wknd_is_the_cover_scene_and_deterministic() {
    let scene = wknd();
    assert!(scene.triangles.is_empty() && scene.positions.is_empty());
    scene.validate().expect("wknd is valid");
    let n = scene.spheres.len();

    let ground = scene.spheres[0];
    assert_eq!(
        (ground.center, ground.radius),
        (Vec3::new(0.0, -1000.0, 0.0), 1000.0)
    );
    assert_eq!(scene.materials[ground.material as usize], Material::DEFAULT);
    let big: Vec<_> = scene.spheres[n - 3..]
        .iter()
        .map(|s| (s.center, s.radius, scene.materials[s.material as usize]))
        .collect();
    assert_eq!(
        big[0],
        (
            Vec3::new(0.0, 1.0, 0.0),
            1.0,
            Material::Dielectric { ior: 1.5 }
        )
    );
    assert_eq!(
        big[1],
        (
            Vec3::new(-4.0, 1.0, 0.0),
            1.0,
            Material::Lambertian {
                albedo: Vec3::new(0.4, 0.2, 0.1)
            }
        )
    );
    assert_eq!(
        big[2],
        (
            Vec3::new(4.0, 1.0, 0.0),
            1.0,
            Material::Metal {
                albedo: Vec3::new(0.7, 0.6, 0.5),
                fuzz: 0.0
            }
        )
    );

    // Small spheres: one per grid cell (a, b) in -11..11, jittered inside the cell, in loop order,
    // none within 0.9 of (4, 0.2, 0); only cells that can reach that region may be missing.
    let small = &scene.spheres[1..n - 3];
    let mut cells = Vec::new();
    let mut kinds = [0usize; 3];
    for s in small {
        assert_eq!((s.radius, s.center.y), (0.2, 0.2));
        let cell = (s.center.x.floor() as i32, s.center.z.floor() as i32);
        assert!(s.center.x - (cell.0 as f32) < 0.9 && s.center.z - (cell.1 as f32) < 0.9);
        assert!((s.center - Vec3::new(4.0, 0.2, 0.0)).length() > 0.9);
        cells.push(cell);
        match scene.materials[s.material as usize] {
            Material::Lambertian { albedo } => {
                assert!(albedo.min_element() >= 0.0 && albedo.max_element() < 1.0);
                kinds[0] += 1;
            }
            Material::Metal { albedo, fuzz } => {
                assert!(albedo.min_element() >= 0.5 && albedo.max_element() < 1.0);
                assert!((0.0..0.5).contains(&fuzz));
                kinds[1] += 1;
            }
            Material::Dielectric { ior } => {
                assert_eq!(ior, 1.5);
                kinds[2] += 1;
            }
            Material::Light { .. } => panic!("wknd has no lights"),
        }
    }
    let mut sorted = cells.clone();
    sorted.sort();
    assert_eq!(
        cells, sorted,
        "small spheres follow the a-then-b loop order"
    );
    sorted.dedup();
    assert_eq!(sorted.len(), cells.len(), "one sphere per cell");
    for a in -11..11 {
        for b in -11..11 {
            if !cells.contains(&(a, b)) {
                assert!(
                    (3..=4).contains(&a) && (-1..=0).contains(&b),
                    "cell ({a}, {b}) missing"
                );
            }
        }
    }
    assert_eq!(n, 1 + cells.len() + 3);
    assert!(cells.len() >= 484 - 4);
    // 80% / 15% / 5% choice: with ~480 draws each share lands well inside these bands.
    let total = cells.len() as f32;
    assert!((0.7..0.9).contains(&(kinds[0] as f32 / total)), "{kinds:?}");
    assert!(
        (0.08..0.22).contains(&(kinds[1] as f32 / total)),
        "{kinds:?}"
    );
    assert!(
        (0.01..0.10).contains(&(kinds[2] as f32 / total)),
        "{kinds:?}"
    );

    let again = load_scene("wknd").expect("wknd by name");
    assert_eq!(again.spheres, scene.spheres);
    assert_eq!(again.materials, scene.materials);
    assert_eq!(again.camera.eye, Vec3::new(13.0, 2.0, 3.0));
    assert_eq!(
        (again.camera.look_at, again.camera.fov_y_deg, again.sky),
        (Vec3::ZERO, 20.0, true)
    );
}

#[test]
fn cornell_box_has_shared_vertices_and_faces_the_right_way() {
    let scene = cornell();
    scene.validate().expect("cornell is valid");
    // 5 walls + 1 light as quads, 2 blocks of 6 quads: 2 triangles per quad.
    assert_eq!(scene.triangles.len(), (5 + 1 + 12) * 2);
    // 8 room corners, 4 light corners, 8 corners per block.
    assert_eq!(scene.positions.len(), 8 + 4 + 8 + 8);
    assert!(scene.spheres.is_empty());
    assert!(!scene.sky);
    assert_eq!(scene.camera.eye, Vec3::new(278.0, 278.0, -800.0));
    assert_eq!(scene.camera.fov_y_deg, 40.0);
    assert_eq!(scene.bounds(), Some((Vec3::ZERO, Vec3::splat(555.0))));

    let room_centre = Vec3::splat(277.5);
    let mut lights = 0;
    for i in 0..scene.triangles.len() {
        let [a, b, c] = scene.triangle(i);
        let normal = (b - a).cross(c - a);
        assert!(normal.length() > 0.0, "triangle {i} is degenerate");
        let centroid = (a + b + c) / 3.0;
        let material = *scene.material_of(i as u32);
        if i < 12 {
            // Walls and light face into the room.
            assert!(
                normal.dot(room_centre - centroid) > 0.0,
                "triangle {i} faces out"
            );
        } else {
            // Block faces face away from their block's centre.
            let block = &scene.triangles[if i < 24 { 12..24 } else { 24..36 }];
            let ids: Vec<u32> = block.iter().flatten().copied().collect();
            let centre = ids
                .iter()
                .map(|&v| scene.positions[v as usize])
                .sum::<Vec3>()
                / ids.len() as f32;
            assert!(
                normal.dot(centroid - centre) > 0.0,
                "block triangle {i} faces in"
            );
            // Inside the room (bottoms rest on the floor).
            assert!(centroid.min_element() >= 0.0 && centroid.max_element() < 555.0);
            assert!(centroid.x > 0.0 && centroid.z > 0.0);
        }
        match material {
            Material::Light { emit } => {
                lights += 1;
                assert_eq!(emit, Vec3::splat(15.0));
                assert_eq!(centroid.y, 554.0);
            }
            Material::Lambertian { albedo } if albedo.x > 0.6 && albedo.y < 0.1 => {
                assert_eq!(centroid.x, 0.0)
            }
            Material::Lambertian { albedo } if albedo.y > 0.4 && albedo.x < 0.2 => {
                assert_eq!(centroid.x, 555.0)
            }
            Material::Lambertian { albedo } => assert_eq!(albedo, Vec3::splat(0.73)),
            other => panic!("unexpected material {other:?}"),
        }
    }
    assert_eq!(lights, 2);
    // The tall block reaches 330 units up, the short one 165.
    let top = |range: std::ops::Range<usize>| {
        scene.triangles[range]
            .iter()
            .flatten()
            .map(|&v| scene.positions[v as usize].y)
            .fold(0.0, f32::max)
    };
    assert_eq!(top(12..24), 165.0);
    assert_eq!(top(24..36), 330.0);
}

#[test]
fn polygons_become_fans_in_face_order_with_global_ids() {
    let dir = temp_dir("fans");
    let path = write(
        &dir,
        "shapes.obj",
        "# a quad, a pentagon (with texture coordinates), then a triangle by relative indices\n\
         vt 0 0\n\
         v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
         v 2 0 0\nv 3 0 0\nv 3 1 0\nv 2.5 2 0\nv 2 1 0\n\
         f 1 2 3 4\n\
         f 5/1 6/1 7/1 8/1 9/1\n\
         f -3 -2 -1\n",
    );
    let scene = load(&path).expect("load shapes.obj");
    let p = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    let expected = [
        [p(0., 0.), p(1., 0.), p(1., 1.)],
        [p(0., 0.), p(1., 1.), p(0., 1.)],
        [p(2., 0.), p(3., 0.), p(3., 1.)],
        [p(2., 0.), p(3., 1.), p(2.5, 2.)],
        [p(2., 0.), p(2.5, 2.), p(2., 1.)],
        [p(3., 1.), p(2.5, 2.), p(2., 1.)],
    ];
    assert_eq!(scene.triangles.len(), expected.len());
    for (id, tri) in expected.iter().enumerate() {
        assert_eq!(&scene.triangle(id), tri, "triangle {id}");
    }
    assert_eq!(
        scene.positions.len(),
        9,
        "vertices are shared, not duplicated per face"
    );
    assert_eq!(scene.name, "shapes");
    assert!(scene.tri_material.iter().all(|&m| m == 0));
    assert!(scene.sky);
    // Default camera: looks at the centre of the bounds from outside them.
    let (min, max) = scene.bounds().unwrap();
    assert_eq!(scene.camera.look_at, (min + max) * 0.5);
    assert!(scene.camera.eye.z > max.z);
    assert!(scene.camera.check().is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mtl_materials_map_as_documented() {
    let dir = temp_dir("mtl");
    write(
        &dir,
        "looks.mtl",
        "newmtl diffuse\nKd 0.1 0.2 0.3\n\
         newmtl lamp\nKd 0 0 0\nKe 4 5 6\n\
         newmtl mirror\nKd 0.9 0.9 0.9\nKs 0.8 0.7 0.6\nNs 1000\nillum 3\n\
         newmtl rough_mirror\nKs 1 1 1\nNs 250\nillum 3\n\
         newmtl brushed\nKd 0.5 0.4 0.3\nKs 0.5 0.5 0.5\nPr 0.25\nPm 1.0\n\
         newmtl glass\nKd 1 1 1\nNi 1.45\nd 0.5\n\
         newmtl glass_model\nillum 7\n\
         newmtl plastic\nKd 0.8 0.8 0.8\nKs 0.5 0.5 0.5\nNs 250\nNi 1.0\nd 1.0\nillum 2\n",
    );
    let names = [
        "diffuse",
        "lamp",
        "mirror",
        "rough_mirror",
        "brushed",
        "glass",
        "glass_model",
        "plastic",
        "undefined",
    ];
    let mut obj = String::from("mtllib looks.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    for name in names {
        obj.push_str(&format!("usemtl {name}\nf 1 2 3\n"));
    }
    let path = write(&dir, "looks.obj", &obj);
    let scene = load(&path).expect("load looks.obj");
    let got: Vec<Material> = (0..scene.triangles.len())
        .map(|i| *scene.material_of(i as u32))
        .collect();
    let expected = [
        Material::DEFAULT, // before any usemtl
        Material::Lambertian {
            albedo: Vec3::new(0.1, 0.2, 0.3),
        },
        Material::Light {
            emit: Vec3::new(4.0, 5.0, 6.0),
        },
        Material::Metal {
            albedo: Vec3::new(0.8, 0.7, 0.6),
            fuzz: 0.0,
        }, // fuzz 1 - sqrt(1000/1000)
        Material::Metal {
            albedo: Vec3::ONE,
            fuzz: 0.5,
        }, // fuzz 1 - sqrt(250/1000)
        Material::Metal {
            albedo: Vec3::new(0.5, 0.4, 0.3),
            fuzz: 0.25,
        }, // Pm: Kd, fuzz Pr
        Material::Dielectric { ior: 1.45 },
        Material::Dielectric { ior: 1.5 }, // no Ni: glass default
        Material::Lambertian {
            albedo: Vec3::splat(0.8),
        }, // Blender's plain diffuse export
        Material::DEFAULT,                 // a name no library defines
    ];
    assert_eq!(got, expected);
    assert_eq!(scene.materials[0], Material::DEFAULT);
    assert_eq!(
        scene.materials.len(),
        9,
        "default + 8 distinct materials, no duplicates"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_mtl_library_is_a_warning_not_an_error() {
    let dir = temp_dir("nomtl");
    let path = write(
        &dir,
        "lonely.obj",
        "mtllib absent.mtl\nusemtl shiny\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    let scene = load(&path).expect("a missing .mtl only warns");
    assert_eq!(scene.triangles.len(), 1);
    assert_eq!(*scene.material_of(0), Material::DEFAULT);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn folder_parts_load_in_file_name_order_with_manifest() {
    let dir = temp_dir("folder");
    // Written b first, a second: sorting by name must put a first.
    write(
        &dir,
        "b_part.obj",
        "v 0 0 2\nv 1 0 2\nv 0 1 2\nv 1 1 2\nf 1 2 3\nf 2 4 3\n",
    );
    write(
        &dir,
        "a_part.obj",
        "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 0 0 2\nf 1 2 3\nf 4 1 2\n",
    );
    let unmanifested = load(&dir).expect("folder without scene.toml");
    assert!(unmanifested.sky);
    assert_eq!(
        unmanifested.name,
        dir.file_name().unwrap().to_str().unwrap()
    );

    write(
        &dir,
        "scene.toml",
        "name = \"TWO\"\ntriangles = 4\nsky = false\n[camera]\neye = [0.5, 0.5, 10]\n\
         look_at = [0.5, 0.5, 0]\nup = [0, 1, 0]\nfov_y_deg = 30\n",
    );
    let scene = load(&dir).expect("folder with scene.toml");
    assert_eq!(scene.name, "TWO");
    assert!(!scene.sky);
    assert_eq!(scene.camera.eye, Vec3::new(0.5, 0.5, 10.0));
    assert_eq!(scene.camera.fov_y_deg, 30.0);
    assert_eq!(scene.triangles.len(), 4);
    let z: Vec<f32> = (0..4).map(|i| scene.triangle(i)[0].z).collect();
    assert_eq!(
        z,
        [1.0, 2.0, 2.0, 2.0],
        "a_part's triangles (z = 1 first) get ids 0 and 1"
    );
    assert_eq!(
        scene.triangle(1),
        [
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0)
        ]
    );
    assert_eq!(
        scene.triangle(2),
        [
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(1.0, 0.0, 2.0),
            Vec3::new(0.0, 1.0, 2.0)
        ]
    );
    // (0, 0, 2) appears in both files and is stored once.
    assert_eq!(scene.positions.len(), 7);
    // The scene.toml path itself names the folder too.
    let via_manifest = load(&dir.join("scene.toml")).expect("load via scene.toml");
    assert_eq!(via_manifest.triangles, scene.triangles);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn errors_name_the_file_and_do_not_panic() {
    let dir = temp_dir("errors");

    let missing = dir.join("nope.obj");
    let msg = load_err(&missing);
    assert!(msg.contains("nope.obj"), "{msg}");
    assert!(matches!(load(&missing), Err(SceneError::Io { .. })));

    let bad_obj = [
        (
            "two_corners.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
            "line 4",
        ),
        (
            "garbage.obj",
            "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n",
            "line 2",
        ),
        (
            "out_of_range.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n",
            "line 5",
        ),
        (
            "zero_index.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            "line 4",
        ),
        (
            "too_far_back.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
            "line 4",
        ),
        (
            "nan.obj",
            "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
            "all 1 triangles use non-finite vertices",
        ),
        (
            "short_vertex.obj",
            "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
            "line 2: a vertex needs x y z",
        ),
        (
            "bad_vt.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n",
            "line 4",
        ),
        ("no_faces.obj", "v 0 0 0\nv 1 0 0\n", "no faces"),
    ];
    for (name, text, needle) in bad_obj {
        let path = write(&dir, name, text);
        let msg = load_err(&path);
        assert!(msg.contains(name) && msg.contains(needle), "{name}: {msg}");
        assert!(!msg.contains('\n'), "one-line message: {msg}");
    }

    // A colour is one number (grey) or three.
    write(&dir, "short.mtl", "newmtl a\nKd 0.5 0.5\n");
    let path = write(
        &dir,
        "short_kd.obj",
        "mtllib short.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    let msg = load_err(&path);
    assert!(msg.contains("short.mtl") && msg.contains("line 2"), "{msg}");

    let camera = "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_y_deg = 40\n";
    let bad_manifests = [
        ("syntax", "name = \"X\n".to_string() + camera, "line 1"),
        ("no_camera", "name = \"X\"\n".to_string(), "camera"),
        (
            "wrong_type",
            camera.replace("[0, 0, 5]", "\"far\""),
            "line 2",
        ),
        ("nan", camera.replace("[0, 0, 5]", "[nan, 0, 5]"), "finite"),
        ("fov", camera.replace("= 40", "= 180"), "fov_y_deg"),
        (
            "same_point",
            camera.replace("[0, 0, 5]", "[0, 0, 0]"),
            "same point",
        ),
        ("unknown_key", format!("skye = false\n{camera}"), "skye"),
    ];
    for (tag, manifest, needle) in bad_manifests {
        let folder = dir.join(tag);
        std::fs::create_dir_all(&folder).unwrap();
        write(&folder, "part.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        write(&folder, "scene.toml", &manifest);
        let msg = load_err(&folder);
        assert!(
            msg.contains("scene.toml") && msg.contains(needle),
            "{tag}: {msg}"
        );
        assert!(!msg.contains('\n'), "one-line message: {msg}");
    }

    let empty = dir.join("empty_folder");
    std::fs::create_dir_all(&empty).unwrap();
    let msg = load_err(&empty);
    assert!(
        msg.contains("empty_folder") && msg.contains(".obj"),
        "{msg}"
    );

    let not_a_scene = write(&dir, "notes.txt", "hello");
    assert!(load_err(&not_a_scene).contains("notes.txt"));

    match load_scene("no-such-scene-anywhere") {
        Err(e @ SceneError::Unknown(_)) => {
            assert!(e.to_string().contains("no-such-scene-anywhere"))
        }
        other => panic!("expected Unknown, got {other:?}"),
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shared_scenes_load_with_manifest_triangle_counts() {
    let Some(shared) = shared_scenes() else {
        eprintln!("skipping: ../shared/scenes not found");
        return;
    };
    for (name, triangles) in [("ship", 6_255), ("bunny", 69_463)] {
        let manifest = Manifest::read(&shared.join(name).join("scene.toml")).expect("manifest");
        assert_eq!(manifest.triangles, Some(triangles as u64));
        let scene = load(&shared.join(name)).expect(name);
        assert_eq!(scene.triangles.len(), triangles, "{name}");
        assert_eq!(Some(scene.camera), manifest.camera.map(|c| c.camera()));
        assert_eq!(scene.sky, manifest.sky);
        // A bare name finds the same folder through the shared-scenes search.
        let by_name = load_scene(name).expect(name);
        assert_eq!(by_name.triangles, scene.triangles);
    }

    let list = list_scenes();
    let names: Vec<&str> = list.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(&names[..3], ["wknd", "cornell", "city"]);
    for folder in ["bath", "bunny", "fox", "lands", "ship", "sponza", "spring"] {
        let info = list
            .iter()
            .find(|s| s.name == folder)
            .unwrap_or_else(|| panic!("{folder} not listed: {names:?}"));
        assert!(matches!(info.kind, SceneKind::Folder(_)));
        assert_eq!(info.counted, CountSource::Manifest);
        assert!(
            info.triangles.is_some_and(|t| t > 0) && info.problem.is_none(),
            "{info:?}"
        );
    }
    assert_eq!(list.len(), 3 + 7);
    let wknd = &list[0];
    assert_eq!(
        (wknd.triangles, wknd.spheres, wknd.counted),
        (Some(0), wknd_sphere_count(), CountSource::Loaded)
    );
    assert_eq!(list[1].prims(), Some(36));
    // The city family is one row with its default budget, counted without generating it.
    assert_eq!(
        (list[2].triangles, list[2].spheres, list[2].counted),
        (Some(1_000_000), 0, CountSource::Loaded)
    );
}

/// Sphere count of the built-in WKND scene.
fn wknd_sphere_count() -> usize {
    wknd().spheres.len()
}
