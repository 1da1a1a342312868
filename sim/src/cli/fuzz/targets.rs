//! The parsers under test, each run on one input as `vtq` runs it, with the invariants an
//! accepted input must keep (a violated one panics, so the harness reports it like a crash).

use std::path::Path;
use std::sync::{Arc, OnceLock};

use glam::Vec3;

use super::mesh_seeds::fuzz_buffer;
use super::Parser;
use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::geometry::Ray;
use crate::model::scene::geometry::{MeshPart, SceneGeometry};
use crate::model::scene::gltf::parse_gltf;
use crate::model::scene::load::scene_from_geometry;
use crate::model::scene::manifest::Manifest;
use crate::model::scene::mtl::{material_from_mtl, parse_mtl, MtlLibrary};
use crate::model::scene::obj::{add_obj, parse_obj};
use crate::model::scene::ply::parse_ply;
use crate::model::scene::text::decode;
use crate::model::scene::{Camera, Material, Scene};
use crate::model::traversal::{trace, Order};
use crate::model::workload::kind::TraceRay;
use crate::model::workload::ray_file::{format_binary, parse_ray_file};
use crate::model::workload::rays_csv::{format_rays, parse_rays};

/// What a parser made of an input (a panic is neither: the harness catches it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Parsed and passed every check.
    Accepted,
    /// Refused with an error.
    Rejected,
}

impl Outcome {
    /// `Accepted` when `ok`.
    fn from_ok(ok: bool) -> Outcome {
        if ok {
            Outcome::Accepted
        } else {
            Outcome::Rejected
        }
    }
}

/// The material library every `mtllib` of a fuzzed OBJ resolves to (names starting with
/// `missing` resolve to no file), with the material names the OBJ seeds use.
pub const FUZZ_LIBRARY: &str = "newmtl red\nKd 0.8 0 0\nnewmtl glass\nNi 1.5\nd 0.1\n\
    newmtl lamp\nKe 4 4 4\nnewmtl metal\nKs 0.9 0.9 0.9\nNs 1000\nillum 3\n";

/// Run `parser` on `input`.
pub fn run(parser: Parser, input: &[u8]) -> Outcome {
    match parser {
        Parser::Obj => obj(input),
        Parser::Mtl => mtl(input),
        Parser::Gltf => gltf(input),
        Parser::Ply => ply(input),
        Parser::SceneToml => Outcome::from_ok(
            Manifest::parse(&String::from_utf8_lossy(input), Path::new("scene.toml")).is_ok(),
        ),
        Parser::Config => {
            let text = String::from_utf8_lossy(input);
            config(SimConfig::load_str(Path::new("fuzz.toml"), &text, &[]))
        }
        Parser::Set => {
            let text = String::from_utf8_lossy(input);
            let overrides: Vec<String> = text.split('\n').map(str::to_string).collect();
            config(SimConfig::load(None, &overrides))
        }
        Parser::RaysCsv => rays(input),
        Parser::RayFile => ray_file(input),
        Parser::BvhCache => bvh(input),
    }
}

/// An OBJ file loaded as `vtq` loads it. Checks: every triangle of the file is loaded or
/// counted as left out.
fn obj(input: &[u8]) -> Outcome {
    static LIBRARY: OnceLock<Arc<MtlLibrary>> = OnceLock::new();
    let library = LIBRARY.get_or_init(|| {
        Arc::new(parse_mtl(FUZZ_LIBRARY, Path::new("lib.mtl")).expect("the fuzz library parses"))
    });
    let path = Path::new("fuzz.obj");
    let Ok(text) = decode(input, path) else {
        return Outcome::Rejected;
    };
    let mut resolve = |name: &str| Ok((!name.starts_with("missing")).then(|| library.clone()));
    let Ok(file) = parse_obj(&text, path, &mut resolve) else {
        return Outcome::Rejected;
    };
    let in_file = file.triangles.len() as u64;
    let mut geometry = SceneGeometry::new();
    if add_obj(&mut geometry, file, path).is_err() {
        return Outcome::Rejected;
    }
    assert_eq!(
        geometry.triangles.len() as u64 + geometry.nonfinite_triangles,
        in_file,
        "every triangle is loaded or counted as left out"
    );
    Outcome::from_ok(scene_from_geometry(geometry, path, "fuzz".into(), None, true).is_ok())
}

/// A glTF or GLB file loaded as `vtq` loads it, every relative buffer URI resolving to
/// [`fuzz_buffer`] (names starting with `missing` to no file). Checks: its camera, if any, is
/// valid, and every triangle is loaded or counted as left out.
fn gltf(input: &[u8]) -> Outcome {
    let path = Path::new("fuzz.gltf");
    let mut resolve =
        |name: &str| Ok((!name.starts_with("missing")).then(|| fuzz_buffer().to_vec()));
    let Ok(file) = parse_gltf(input, path, &mut resolve) else {
        return Outcome::Rejected;
    };
    if let Some(camera) = file.camera {
        if let Err(e) = camera.check() {
            panic!("an accepted glTF camera is not valid: {e}");
        }
    }
    mesh(file.part, path, file.camera)
}

/// A PLY file loaded as `vtq` loads it. Checks: every triangle is loaded or counted as left
/// out.
fn ply(input: &[u8]) -> Outcome {
    let path = Path::new("fuzz.ply");
    match parse_ply(input, path) {
        Ok(file) => mesh(file.part, path, None),
        Err(_) => Outcome::Rejected,
    }
}

/// A mesh part a reader accepted, merged into scene geometry and made a scene. Checks: the
/// merge accepts it (its triangles index its vertices) and every triangle is loaded or counted
/// as left out.
fn mesh(part: MeshPart, path: &Path, camera: Option<Camera>) -> Outcome {
    let mut geometry = SceneGeometry::new();
    if let Err(e) = geometry.add_part(&part, path) {
        panic!("an accepted mesh does not merge: {e}");
    }
    assert_eq!(
        geometry.triangles.len() + geometry.nonfinite_triangles as usize,
        part.triangles.len(),
        "every triangle is loaded or counted as left out"
    );
    Outcome::from_ok(scene_from_geometry(geometry, path, "fuzz".into(), camera, true).is_ok())
}

/// A material library. Checks: every material it maps to passes [`Scene::validate`].
fn mtl(input: &[u8]) -> Outcome {
    let path = Path::new("fuzz.mtl");
    let Ok(text) = decode(input, path) else {
        return Outcome::Rejected;
    };
    let Ok(library) = parse_mtl(&text, path) else {
        return Outcome::Rejected;
    };
    let mut materials = vec![Material::DEFAULT];
    materials.extend(library.materials.iter().map(material_from_mtl));
    let scene = Scene {
        name: "fuzz".into(),
        positions: Vec::new(),
        triangles: Vec::new(),
        tri_material: Vec::new(),
        spheres: Vec::new(),
        materials,
        camera: Camera::framing(Vec3::ZERO, Vec3::ONE),
        sky: true,
    };
    if let Err(e) = scene.validate() {
        panic!("an accepted library maps to an invalid material: {e}");
    }
    Outcome::Accepted
}

/// A configuration's outcome. Checks: an accepted configuration writes out as TOML that reads
/// back to the same configuration.
fn config(loaded: Result<SimConfig, crate::model::config::ConfigError>) -> Outcome {
    let Ok(config) = loaded else {
        return Outcome::Rejected;
    };
    let text = config
        .to_toml()
        .unwrap_or_else(|e| panic!("an accepted configuration does not write out: {e}"));
    let again = SimConfig::load_str(Path::new("echo.toml"), &text, &[])
        .unwrap_or_else(|e| panic!("an accepted configuration does not read back: {e}"));
    assert_eq!(again, config, "the configuration changes on a round trip");
    Outcome::Accepted
}

/// A rays CSV file. Checks: accepted rays write out and read back bit-identically (a NaN as a
/// NaN: its sign and payload are not written), occlusion flags included.
fn rays(input: &[u8]) -> Outcome {
    let Ok(rays) = parse_rays("fuzz.csv", input) else {
        return Outcome::Rejected;
    };
    let mut text = Vec::new();
    format_rays(&mut text, &rays).expect("writing to memory");
    let again = parse_rays("echo.csv", text.as_slice())
        .unwrap_or_else(|e| panic!("accepted rays do not read back: {e}"));
    let bits = |r: &[TraceRay]| -> Vec<([u32; 8], bool)> {
        r.iter()
            .map(|TraceRay { ray: r, occlusion }| {
                let words = [
                    r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax,
                ]
                .map(|x| {
                    if x.is_nan() {
                        f32::NAN.to_bits()
                    } else {
                        x.to_bits()
                    }
                });
                (words, *occlusion)
            })
            .collect()
    };
    assert_eq!(bits(&again), bits(&rays), "rays change on a round trip");
    Outcome::Accepted
}

/// A ray file in either form. Checks: accepted rays write out in the binary form and read
/// back bit-identically (NaN payloads included), occlusion flags included.
fn ray_file(input: &[u8]) -> Outcome {
    let Ok(rays) = parse_ray_file("fuzz.bin", input) else {
        return Outcome::Rejected;
    };
    let bytes = format_binary(&rays);
    let again = parse_ray_file("echo.bin", &bytes)
        .unwrap_or_else(|e| panic!("accepted rays do not read back: {e}"));
    assert_eq!(format_binary(&again), bytes, "rays change on a round trip");
    Outcome::Accepted
}

/// A BVH cache file. Checks: an accepted file serializes back to the same bytes, and rays
/// traverse it in both orders without a panic.
fn bvh(input: &[u8]) -> Outcome {
    let Ok(bvh) = HwBvh::from_bytes(input) else {
        return Outcome::Rejected;
    };
    assert!(
        bvh.to_bytes() == input,
        "an accepted cache file does not serialize back to its bytes"
    );
    let origins = [
        Vec3::new(0.1, 0.2, 5.0),
        Vec3::new(-3.0, 1.0, -2.0),
        Vec3::ZERO,
    ];
    for origin in origins {
        for dir in [Vec3::NEG_Z, Vec3::new(0.3, -0.2, 0.9), Vec3::X] {
            let ray = Ray::new(origin, dir);
            trace(&bvh, &ray, Order::RayStationary);
            trace(&bvh, &ray, Order::Treelet);
        }
    }
    Outcome::Accepted
}
