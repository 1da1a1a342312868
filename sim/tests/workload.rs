//! The LumiBench path-tracing workload: random numbers, path termination, simple scenes with known
//! radiance, and determinism (repeat renders and serial vs parallel renders are bit-identical).

use glam::Vec3;
use vtq_sim::model::scene::{Camera, Material, Scene, Sphere};
use vtq_sim::model::workload::camera::CameraFrame;
use vtq_sim::model::workload::pathtracer::{
    render, render_serial, sky, BruteForce, PathState, Render, RenderSettings, Tracer,
};
use vtq_sim::model::workload::rng::{tea, Rng};

/// TEA written independently of the crate: 64-bit arithmetic, masked to 32 bits after every
/// step (the low 32 bits of a sum or XOR depend only on the low 32 bits of the operands).
fn reference_tea(rounds: u32, v0: u32, v1: u32) -> u32 {
    let low = |x: u64| x & 0xFFFF_FFFF;
    let mix = |v: u64, s: u64, k0: u64, k1: u64| {
        let a = low(low(v << 4) + k0);
        let b = low(v + s);
        let c = low((v >> 5) + k1);
        (a ^ b) ^ c
    };
    let (mut v0, mut v1, mut s0) = (u64::from(v0), u64::from(v1), 0u64);
    for _ in 0..rounds {
        s0 = low(s0 + 0x9e37_79b9);
        v0 = low(v0 + mix(v1, s0, 0xa341_316c, 0xc801_3ea4));
        v1 = low(v1 + mix(v0, s0, 0xad90_777d, 0x7e95_761e));
    }
    v0 as u32
}

#[test]
fn tea_matches_an_independent_implementation() {
    for (a, b) in [
        (0, 0),
        (1, 0),
        (65535, 3),
        (u32::MAX, u32::MAX),
        (123_456, 789),
    ] {
        assert_eq!(tea(16, a, b), reference_tea(16, a, b), "tea<16>({a}, {b})");
        assert_eq!(Rng::for_pixel(a, b).state(), reference_tea(16, a, b));
    }
}

#[test]
fn tea_seeds_are_distinct_per_pixel() {
    // Only v0 of the TEA output is kept, so seeds behave like random 32-bit values: among the
    // 65536 pixels of a 256x256 image the birthday bound expects 65536^2 / 2^33 = 0.5 equal
    // pairs. Neighbouring pixels, which share a warp, must all differ.
    let (w, h) = (256u32, 256u32);
    let seed = |x: u32, y: u32| Rng::for_pixel(y * w + x, 0).state();
    for y in 0..h {
        for x in 0..w {
            for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                if x + dx < w && y + dy < h {
                    assert_ne!(seed(x, y), seed(x + dx, y + dy), "pixel ({x}, {y})");
                }
            }
        }
    }
    let mut seeds: Vec<u32> = (0..w * h).map(|p| Rng::for_pixel(p, 0).state()).collect();
    seeds.sort_unstable();
    seeds.dedup();
    assert!(
        seeds.len() >= 65536 - 4,
        "{} equal seeds",
        65536 - seeds.len()
    );
    assert_ne!(Rng::for_pixel(5, 0).state(), Rng::for_pixel(5, 1).state());
}

#[test]
fn floats_are_in_unit_interval_and_roughly_uniform() {
    let mut rng = Rng::for_pixel(42, 0);
    let n = 100_000;
    let mut sum = 0.0f64;
    let mut below_tenth = 0;
    for _ in 0..n {
        let x = rng.next_f32();
        assert!((0.0..1.0).contains(&x), "{x} outside [0, 1)");
        sum += f64::from(x);
        below_tenth += usize::from(x < 0.1);
    }
    // Uniform: mean 0.5 (std error ~0.001), 10% below 0.1 (std error ~0.1%).
    assert!((sum / f64::from(n) - 0.5).abs() < 0.01);
    assert!((below_tenth as f64 / f64::from(n) - 0.1).abs() < 0.01);
}

#[test]
fn same_seed_same_stream() {
    let mut a = Rng::for_pixel(77, 2);
    let mut b = Rng::for_pixel(77, 2);
    for _ in 0..100 {
        assert_eq!(a.next_u24(), b.next_u24());
    }
}

fn camera_looking_down_neg_z() -> Camera {
    Camera {
        eye: Vec3::ZERO,
        look_at: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        fov_y_deg: 60.0,
    }
}

fn empty_scene(sky: bool) -> Scene {
    Scene {
        name: "empty".into(),
        positions: vec![],
        triangles: vec![],
        tri_material: vec![],
        spheres: vec![],
        materials: vec![Material::DEFAULT],
        camera: camera_looking_down_neg_z(),
        sky,
    }
}

fn settings(width: u32, height: u32, bounces: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp: 1,
        bounces,
        ..RenderSettings::default()
    }
}

/// A scene with every material: a glass, a metal and a diffuse sphere on a diffuse ground quad,
/// under an emissive triangle, with a sky.
fn mixed_scene() -> Scene {
    let mut s = empty_scene(true);
    s.name = "mixed".into();
    s.camera = Camera {
        eye: Vec3::new(0.0, 1.0, 4.0),
        look_at: Vec3::new(0.0, 0.5, 0.0),
        up: Vec3::Y,
        fov_y_deg: 50.0,
    };
    s.materials.extend([
        Material::Dielectric { ior: 1.5 },
        Material::Metal {
            albedo: Vec3::new(0.8, 0.6, 0.2),
            fuzz: 0.3,
        },
        Material::Lambertian {
            albedo: Vec3::new(0.1, 0.2, 0.5),
        },
        Material::Light {
            emit: Vec3::splat(4.0),
        },
    ]);
    s.positions = vec![
        Vec3::new(-5.0, 0.0, -5.0),
        Vec3::new(5.0, 0.0, -5.0),
        Vec3::new(5.0, 0.0, 5.0),
        Vec3::new(-5.0, 0.0, 5.0),
        Vec3::new(-1.0, 3.0, -1.0),
        Vec3::new(1.0, 3.0, -1.0),
        Vec3::new(0.0, 3.0, 1.0),
    ];
    s.triangles = vec![[0, 2, 1], [0, 3, 2], [4, 5, 6]];
    s.tri_material = vec![0, 0, 4];
    s.spheres = vec![
        Sphere {
            center: Vec3::new(-1.2, 0.5, 0.0),
            radius: 0.5,
            material: 1,
        },
        Sphere {
            center: Vec3::new(0.0, 0.5, 0.0),
            radius: 0.5,
            material: 2,
        },
        Sphere {
            center: Vec3::new(1.2, 0.5, 0.0),
            radius: 0.5,
            material: 3,
        },
    ];
    s
}

fn assert_renders_identical(a: &Render, b: &Render) {
    assert_eq!(a.ray_offsets, b.ray_offsets);
    assert_eq!(a.rays.len(), b.rays.len());
    for (x, y) in a.rays.iter().zip(&b.rays) {
        assert_eq!(
            x.origin.to_array().map(f32::to_bits),
            y.origin.to_array().map(f32::to_bits)
        );
        assert_eq!(
            x.dir.to_array().map(f32::to_bits),
            y.dir.to_array().map(f32::to_bits)
        );
    }
    for (x, y) in a.image.iter().zip(&b.image) {
        assert_eq!(
            x.to_array().map(f32::to_bits),
            y.to_array().map(f32::to_bits)
        );
    }
    assert_eq!(a.stats.rays_traced, b.stats.rays_traced);
    assert_eq!(a.stats.nonfinite_samples, b.stats.nonfinite_samples);
}

#[test]
fn paths_inside_a_closed_diffuse_sphere_trace_exactly_one_plus_bounces_rays() {
    // Every ray hits the enclosing sphere and every hit scatters, so only the bounce limit
    // ends a path; nothing emits and nothing escapes, so the radiance is zero.
    let mut scene = empty_scene(true);
    scene.spheres.push(Sphere {
        center: Vec3::ZERO,
        radius: 10.0,
        material: 0,
    });
    let tracer = BruteForce { scene: &scene };
    for bounces in 0..5 {
        let s = settings(4, 4, bounces);
        let frame = CameraFrame::new(&scene.camera, s.width, s.height).unwrap();
        for pixel in 0..16 {
            let (mut state, mut ray) = PathState::new(&frame, &s, pixel, 0);
            let mut traced = 1;
            while let Some(next) = state.on_hit(&scene, tracer.closest_hit(&ray)) {
                traced += 1;
                assert!(traced <= 1 + bounces, "path exceeded 1 + {bounces} rays");
                ray = next;
            }
            assert_eq!(traced, 1 + bounces);
            assert_eq!(state.rays(), 1 + bounces);
            assert!(state.is_done());
            assert_eq!(state.radiance(), Vec3::ZERO);
            assert_eq!(
                state.on_hit(&scene, None),
                None,
                "an ended path stays ended"
            );
            assert_eq!(state.radiance(), Vec3::ZERO);
        }
    }
}

#[test]
fn an_emissive_quad_filling_the_view_gives_its_colour() {
    let emit = Vec3::new(0.3, 0.6, 0.9);
    let mut scene = empty_scene(true);
    scene.materials.push(Material::Light { emit });
    scene.positions = vec![
        Vec3::new(-10.0, -10.0, -1.0),
        Vec3::new(10.0, -10.0, -1.0),
        Vec3::new(10.0, 10.0, -1.0),
        Vec3::new(-10.0, 10.0, -1.0),
    ];
    scene.triangles = vec![[0, 1, 2], [0, 2, 3]];
    scene.tri_material = vec![1, 1];
    let r = render(
        &scene,
        &BruteForce { scene: &scene },
        &settings(8, 6, 3),
        None,
    )
    .unwrap();
    assert_eq!(r.image.len(), 48);
    assert!(r.image.iter().all(|&c| c == emit), "{:?}", r.image);
    assert_eq!(
        r.stats.rays_traced, 48,
        "a light ends the path at the primary hit"
    );
    assert_eq!(r.stats.nonfinite_samples, 0);
}

#[test]
fn nonfinite_radiance_is_counted_and_written_black() {
    // Scene::validate rejects infinite emission, but a hand-built scene can hold it: the render
    // must count every such sample and keep it out of the image.
    let mut scene = empty_scene(false);
    scene.materials.push(Material::Light {
        emit: Vec3::new(f32::INFINITY, 1.0, 1.0),
    });
    scene.spheres.push(Sphere {
        center: Vec3::new(0.0, 0.0, -3.0),
        radius: 100.0,
        material: 1,
    });
    // The camera is inside the sphere, so every primary ray hits the light.
    let s = RenderSettings {
        spp: 3,
        ..settings(4, 4, 3)
    };
    let r = render(&scene, &BruteForce { scene: &scene }, &s, None).unwrap();
    assert_eq!(r.stats.nonfinite_samples, 16 * 3);
    assert!(r.image.iter().all(|&c| c == Vec3::ZERO));
}

#[test]
fn an_empty_scene_shows_the_sky_gradient_or_black() {
    let scene = empty_scene(true);
    let r = render(
        &scene,
        &BruteForce { scene: &scene },
        &settings(4, 8, 3),
        None,
    )
    .unwrap();
    for p in 0..32 {
        let rays = r.pixel_rays(p);
        assert_eq!(rays.len(), 1);
        let a = 0.5 * (rays[0].dir.normalize().y + 1.0);
        let expected = Vec3::ONE * (1.0 - a) + Vec3::new(0.5, 0.7, 1.0) * a;
        assert!((r.image[p] - expected).abs().max_element() < 1e-6);
        assert_eq!(r.image[p], sky(&scene, rays[0].dir));
    }
    // Row 0 is the top of the image: it looks up, into the bluer part of the gradient.
    assert!(r.image[0].x < r.image[31].x);

    let dark = empty_scene(false);
    let r = render(
        &dark,
        &BruteForce { scene: &dark },
        &settings(4, 4, 3),
        None,
    )
    .unwrap();
    assert!(r.image.iter().all(|&c| c == Vec3::ZERO));
}

#[test]
fn a_path_state_driven_by_hand_reproduces_the_render() {
    // The cycle-level simulator drives PathState itself: it must see the same rays as render().
    let scene = mixed_scene();
    let tracer = BruteForce { scene: &scene };
    let s = settings(12, 10, 3);
    let r = render(&scene, &tracer, &s, None).unwrap();
    let frame = CameraFrame::new(&scene.camera, s.width, s.height).unwrap();
    for pixel in [0u32, 17, 60, 119] {
        let (mut state, mut ray) = PathState::new(&frame, &s, pixel, 0);
        let mut rays = vec![ray];
        while let Some(next) = state.on_hit(&scene, tracer.closest_hit(&ray)) {
            rays.push(next);
            ray = next;
        }
        assert_eq!(rays.as_slice(), r.pixel_rays(pixel as usize));
        assert_eq!(state.radiance(), r.image[pixel as usize]);
    }
}

#[test]
fn repeated_renders_trace_identical_rays() {
    let scene = mixed_scene();
    let tracer = BruteForce { scene: &scene };
    let s = settings(16, 12, 3);
    let a = render(&scene, &tracer, &s, None).unwrap();
    let b = render(&scene, &tracer, &s, None).unwrap();
    assert_renders_identical(&a, &b);
    // The scene exercises secondary rays, lights and the sky.
    // The ground fills more than half of the view (rays from 6.3 to 32 degrees below the
    // horizontal reach it, of a 50-degree field of view centred 7 degrees down), and every
    // ground hit traces a secondary ray.
    let pixels = 16.0 * 12.0;
    assert!(
        a.stats.rays_traced as f64 > 1.4 * pixels,
        "{} rays",
        a.stats.rays_traced
    );
    assert!(
        a.image.iter().any(|c| c.max_element() > 1.0),
        "the light must be visible"
    );
    assert_eq!(a.stats.nonfinite_samples, 0);
}

#[test]
fn serial_and_parallel_renders_are_bit_identical() {
    let scene = mixed_scene();
    let tracer = BruteForce { scene: &scene };
    let s = RenderSettings {
        width: 20,
        height: 16,
        spp: 2,
        bounces: 4,
        ..RenderSettings::default()
    };
    let parallel = render(&scene, &tracer, &s, None).unwrap();
    let serial = render_serial(&scene, &tracer, &s, None).unwrap();
    assert_renders_identical(&parallel, &serial);
    assert_eq!(*parallel.ray_offsets.last().unwrap(), parallel.rays.len());
}

#[test]
fn bad_settings_and_cameras_are_errors() {
    let scene = empty_scene(true);
    let tracer = BruteForce { scene: &scene };
    let zero = settings(0, 4, 3);
    let e = render(&scene, &tracer, &zero, None).unwrap_err();
    assert!(e.to_string().contains("width"), "{e}");
    let mut bad = empty_scene(true);
    bad.camera.look_at = bad.camera.eye;
    let e = render(&bad, &BruteForce { scene: &bad }, &settings(4, 4, 3), None).unwrap_err();
    assert!(e.to_string().contains("camera"), "{e}");
}

/// Next-event estimation is an estimator of the same light as the path tracer's: on cornell
/// (lit by an emitting quad: shadow rays toward it) and wknd (lit by its sky: shadow rays
/// toward the sky) the mean radiance of many samples agrees within 5% (measured: 1.3% and
/// 1.1%).
#[test]
fn next_event_estimation_estimates_the_path_tracers_light() {
    use vtq_sim::model::bvh::{BvhParams, HwBvh};
    use vtq_sim::model::scene::load::load_scene;
    use vtq_sim::model::workload::kind::WorkloadKind;
    for (name, spp) in [("cornell", 256), ("wknd", 64)] {
        let scene = load_scene(name).unwrap();
        let bvh = HwBvh::build(&scene, &BvhParams::default()).unwrap();
        let mut s = settings(16, 16, 3);
        s.spp = spp;
        let path = render(&scene, &bvh, &s, None).unwrap();
        s.kind = WorkloadKind::PathNee;
        let nee = render(&scene, &bvh, &s, None).unwrap();
        assert!(nee.stats.occlusion_rays > 0, "{name}: shadow rays");
        let mean =
            |r: &Render| r.image.iter().copied().sum::<Vec3>().element_sum() / r.image.len() as f32;
        let (a, b) = (mean(&path), mean(&nee));
        assert!(
            (a - b).abs() < 0.05 * a,
            "{name}: path tracer {a}, with NEE {b}"
        );
    }
}
