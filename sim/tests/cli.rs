//! End-to-end tests of the `vtq` binary: render, trace, scenes, help, the hardware commands
//! (area, verilog, cosim), and one-line errors for bad input.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use vtq_gen::synth::lint;
use vtq_gen::tools::{or_skip, CI_ENV};
use vtq_sim::model::bvh::{BvhParams, HwBvh};
use vtq_sim::model::geometry::Ray;
use vtq_sim::model::scene::load::load_scene;
use vtq_sim::model::traversal::{trace, Order};
use vtq_sim::model::workload::kind::TraceRay;
use vtq_sim::model::workload::rays_csv::write_rays;

/// A fresh temporary folder for one test.
fn temp_dir(test: &str) -> PathBuf {
    common::fresh_dir(&format!("cli-{test}"))
}

fn vtq(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vtq"))
        .args(args)
        .output()
        .expect("the vtq binary runs")
}

/// Assert the command failed with exactly one `error: ...` line mentioning `needle`.
fn assert_one_line_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "stderr: {stderr}");
    assert_eq!(
        stderr.trim_end().lines().last(),
        Some(errors[0]),
        "the error is the last line"
    );
    assert!(
        errors[0].contains(needle),
        "'{needle}' not in: {}",
        errors[0]
    );
}

#[test]
fn help_documents_every_option() {
    let out = vtq(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for sub in ["scenes", "render", "trace", "bench"] {
        assert!(text.contains(sub), "--help lacks {sub}: {text}");
    }
    let out = vtq(&["render", "--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for opt in [
        "--scene",
        "--out",
        "--width",
        "--height",
        "--spp",
        "--bounces",
        "--bvh-width",
        "--treelet-bytes",
        "--cache-dir",
        "--no-cache",
    ] {
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with(opt))
            .unwrap_or_else(|| panic!("render --help lacks {opt}: {text}"));
        assert!(
            line.trim_start().len() > opt.len() + 10,
            "{opt} has no description: {line}"
        );
    }
}

#[test]
fn scenes_lists_the_built_ins() {
    let out = vtq(&["scenes"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let wknd = text
        .lines()
        .find(|l| l.starts_with("wknd "))
        .expect("wknd listed");
    let spheres = load_scene("wknd").unwrap().spheres.len();
    let cells: Vec<&str> = wknd.split_whitespace().collect();
    // scene, label, triangles, spheres, primitives.
    let n = spheres.to_string();
    assert_eq!(cells[2..5], ["0", n.as_str(), n.as_str()], "{wknd}");
    assert!(text.lines().any(|l| l.starts_with("cornell ")), "{text}");
}

#[test]
fn render_writes_a_png_of_the_requested_size() {
    let dir = temp_dir("render");
    let png_path = dir.join("wknd.png");
    let out = vtq(&[
        "render",
        "--scene",
        "wknd",
        "--width",
        "32",
        "--height",
        "24",
        "--out",
        png_path.to_str().unwrap(),
        "--cache-dir",
        dir.join("cache").to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("rays/s"), "{stdout}");
    assert!(stdout.contains("treelets"), "{stdout}");

    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&png_path).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (32, 24));
    let pixels: Vec<&[u8]> = buf[..info.buffer_size()].chunks(3).collect();
    assert!(
        pixels.iter().any(|p| *p != pixels[0]),
        "the image is one colour"
    );
    // The wknd camera looks at the horizon: the top row is sky (blue above red).
    assert!(pixels[0][2] > pixels[0][0], "{:?}", pixels[0]);

    // --rays-out writes every traced ray, readable by `vtq trace`.
    let rays_path = dir.join("rays.csv");
    let out = vtq(&[
        "render",
        "--scene",
        "cornell",
        "--width",
        "6",
        "--height",
        "5",
        "--out",
        png_path.to_str().unwrap(),
        "--rays-out",
        rays_path.to_str().unwrap(),
        "--no-cache",
    ]);
    assert!(out.status.success());
    let rays = vtq_sim::model::workload::rays_csv::read_rays(&rays_path).unwrap();
    assert!(
        rays.len() >= 30 && rays.len() <= 30 * 4,
        "{} rays",
        rays.len()
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(&format!(": {} rays in", rays.len())),
        "{stdout}"
    );

    // A second run loads the BVH from the cache.
    let again = vtq(&[
        "render",
        "--scene",
        "wknd",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        png_path.to_str().unwrap(),
        "--cache-dir",
        dir.join("cache").to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&again.stdout).contains("loaded from the cache"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn trace_reports_nan_and_inf_rays_as_misses_and_matches_traversal() {
    let dir = temp_dir("trace");
    let scene = load_scene("cornell").unwrap();
    let cam = scene.camera;
    let target = cam.look_at;
    let mut rays: Vec<Ray> = (0..12)
        .map(|i| {
            let off = Vec3::new((i % 4) as f32 - 1.5, (i / 4) as f32 - 1.0, 0.0)
                * 0.1
                * (target - cam.eye).length();
            Ray::new(cam.eye, (target + off - cam.eye).normalize())
        })
        .collect();
    rays.push(Ray {
        origin: cam.eye,
        dir: Vec3::new(f32::NAN, 0.0, -1.0),
        tmin: 0.0,
        tmax: 1e4,
    });
    rays.push(Ray {
        origin: Vec3::new(f32::INFINITY, 0.0, 0.0),
        dir: Vec3::new(0.0, 0.0, -1.0),
        tmin: 0.0,
        tmax: 1e4,
    });
    let rays_path = dir.join("rays.csv");
    let closest: Vec<TraceRay> = (rays.iter())
        .map(|&ray| TraceRay {
            ray,
            occlusion: false,
        })
        .collect();
    write_rays(&rays_path, &closest).unwrap();
    let text = std::fs::read_to_string(&rays_path).unwrap();
    assert!(text.contains("NaN") && text.contains("inf"), "{text}");

    let hits_path = dir.join("hits.csv");
    for order in ["ray", "treelet"] {
        let out = vtq(&[
            "trace",
            "--scene",
            "cornell",
            "--rays",
            rays_path.to_str().unwrap(),
            "--out",
            hits_path.to_str().unwrap(),
            "--order",
            order,
            "--no-cache",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );

        let bvh = HwBvh::build(&scene, &BvhParams::default()).unwrap();
        let text = std::fs::read_to_string(&hits_path).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("ray,hit,t,prim,u,v"));
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), rays.len());
        let mut hits = 0;
        for (i, (row, ray)) in rows.iter().zip(&rays).enumerate() {
            assert_eq!(row[0], i.to_string());
            match trace(&bvh, ray, Order::RayStationary) {
                Some(h) => {
                    hits += 1;
                    assert_eq!(row[1], "1");
                    assert_eq!(row[2].parse::<f32>().unwrap(), h.t);
                    assert_eq!(row[3], h.prim.to_string());
                    assert_eq!(row[4].parse::<f32>().unwrap(), h.u);
                    assert_eq!(row[5].parse::<f32>().unwrap(), h.v);
                }
                None => assert_eq!(row[1..], ["0", "inf", "-1", "0", "0"]),
            }
        }
        assert_eq!(hits, 12, "every ray aimed into the closed box hits");
        assert_eq!(rows[12][1], "0", "NaN ray is a miss");
        assert_eq!(rows[13][1], "0", "inf ray is a miss");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_scene_file_is_a_one_line_error() {
    let out = vtq(&[
        "render",
        "--scene",
        "/nonexistent/vtq/scene.obj",
        "--no-cache",
    ]);
    assert_one_line_error(&out, "/nonexistent/vtq/scene.obj");
}

#[test]
fn malformed_obj_is_a_one_line_error() {
    let dir = temp_dir("bad-obj");
    let obj = dir.join("broken.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n").unwrap();
    let out = vtq(&["render", "--scene", obj.to_str().unwrap(), "--no-cache"]);
    assert_one_line_error(&out, "broken.obj");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_prints_ignored_statements_and_left_out_triangles() {
    let dir = temp_dir("ignored");
    std::fs::write(
        dir.join("looks.mtl"),
        "newmtl red\nKa 1 1 1\nKd 1 0 0\nmap_Kd red.png\nmap_Kd again.png\n",
    )
    .unwrap();
    let obj = dir.join("quirky.obj");
    std::fs::write(
        &obj,
        "\u{FEFF}mtllib looks.mtl\r\nmtllib gone.mtl\r\no\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\n\
         v nan 0 0\r\nvp 0.5\r\nl 1 2\r\nl 2 3\r\nusemtl red\r\nf 1 2 3\r\nusemtl \r\n\
         f 1 2 4\r\nusemtl nothing\r\nf 3 2 1\r\n",
    )
    .unwrap();
    let out = vtq(&[
        "render",
        "--scene",
        obj.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        dir.join("q.png").to_str().unwrap(),
        "--no-cache",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("scene quirky: 2 triangles, 0 spheres, 2 materials"),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            "scene quirky: ignored: o x1, vp x1, l x2; in .mtl files: Ka x1, map_Kd x2\n"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("scene quirky: left out: 1 triangle using 1 non-finite vertex"),
        "{stdout}"
    );
    assert!(
        stderr.contains("warning: scene quirky: 1 material library not found")
            && stderr.contains("gone.mtl")
            && stderr.contains("(first: 'nothing')"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn malformed_csv_is_a_one_line_error() {
    let dir = temp_dir("bad-csv");
    let csv = dir.join("rays.csv");
    std::fs::write(
        &csv,
        "ox,oy,oz,dx,dy,dz,tmin,tmax\n0,0,0,0,0,-1,0,1\n0,0,zero,0,0,-1,0,1\n",
    )
    .unwrap();
    let out = vtq(&[
        "trace",
        "--scene",
        "cornell",
        "--rays",
        csv.to_str().unwrap(),
        "--out",
        dir.join("hits.csv").to_str().unwrap(),
        "--no-cache",
    ]);
    assert_one_line_error(&out, "rays.csv:3: column 3 (oz)");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_scene_manifest_is_a_one_line_error() {
    let dir = temp_dir("bad-toml");
    let scene = dir.join("scene");
    std::fs::create_dir_all(&scene).unwrap();
    std::fs::write(
        scene.join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(scene.join("scene.toml"), "name = \"x\"\n[camera\neye = 1\n").unwrap();
    let out = vtq(&["render", "--scene", scene.to_str().unwrap(), "--no-cache"]);
    assert_one_line_error(&out, "scene.toml");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn out_of_range_options_are_one_line_errors() {
    let out = vtq(&["render", "--scene", "cornell", "--width", "0", "--no-cache"]);
    assert_one_line_error(&out, "width");
    let out = vtq(&[
        "render",
        "--scene",
        "cornell",
        "--bvh-width",
        "9",
        "--no-cache",
    ]);
    assert_one_line_error(&out, "width 9");
}

#[test]
fn bench_agrees_with_obvhs() {
    let out = vtq(&[
        "bench", "--scene", "cornell", "--width", "12", "--height", "10",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("ratio ours/obvhs"), "{stdout}");
    // Both sides use the same leaf tests, so every closest-hit distance must agree.
    let line = stdout
        .lines()
        .find(|l| l.starts_with("agreement:"))
        .expect("agreement line");
    let n = stdout
        .lines()
        .find_map(|l| l.strip_prefix("rays:  "))
        .and_then(|l| l.split_whitespace().next())
        .expect("ray count");
    assert!(
        line.contains(&format!("same t on {n} (100.000%)")),
        "{line}"
    );
}

/// The `vtq` output of a command that must succeed, as text.
fn vtq_ok(args: &[&str]) -> String {
    let out = vtq(args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "vtq {args:?}: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The output of a `vtq cosim` command that must succeed; `None` (the test skips) when the
/// HDL simulator is not installed, outside CI.
fn vtq_cosim(args: &[&str]) -> Option<String> {
    let out = vtq(args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success()
        && stderr.contains("is not installed")
        && std::env::var_os(CI_ENV).is_none()
    {
        eprintln!("skipping: {}", stderr.trim());
        return None;
    }
    assert!(out.status.success(), "{stdout}{stderr}");
    Some(stdout)
}

/// `vtq cosim` ([`vtq_cosim`]) for `cycles` cycles with its files in `dir`, then `args`, then
/// each of `sets` as a `--set`.
fn cosim_in(dir: &Path, cycles: &str, args: &[&str], sets: &[&str]) -> Option<String> {
    let mut all = vec![
        "cosim",
        "--cycles",
        cycles,
        "--work-dir",
        dir.to_str().unwrap(),
    ];
    all.extend(args);
    for set in sets {
        all.extend(["--set", set]);
    }
    vtq_cosim(&all)
}

/// The line of `text` that starts with `start`.
fn line_starting<'a>(text: &'a str, start: &str) -> &'a str {
    text.lines()
        .find(|l| l.starts_with(start))
        .unwrap_or_else(|| panic!("no line starting with '{start}' in:\n{text}"))
}

/// Asserts the line of `text` that starts with `start` contains `needle`.
fn assert_line_contains(text: &str, start: &str, needle: &str) {
    let line = line_starting(text, start);
    assert!(line.contains(needle), "{line}");
}

/// Asserts `vtq cosim`'s summary line of `module` (in its output `stdout`) compared `cycles`
/// cycles without a mismatch.
fn assert_all_compared(stdout: &str, module: &str, cycles: &str) {
    assert_line_contains(
        stdout,
        &format!("{module}: "),
        &format!("{cycles} cycles compared, 0 mismatches"),
    );
}

#[test]
fn area_reports_the_paper_sizes() {
    let text = vtq_ok(&["area"]);
    // Paper 6.5: 600 x 31 bits = 2325 B (printed "2.2 KB" in the paper, "2.27 KB" by us),
    // 128 x (19 + 32 x 12) bits = 6448 B = 6.29 KB, 4096 rays x 32 B = 128 KB.
    let count = line_starting(&text, "treelet count table  RT unit");
    assert!(
        count.contains("2.27 KB") && count.contains("2.2 KB"),
        "{count}"
    );
    assert_line_contains(&text, "treelet queue table  L1", "6.29 KB");
    assert_line_contains(&text, "ray records          L2", "128 KB");

    let json: serde_json::Value =
        serde_json::from_str(&vtq_ok(&["area", "--json"])).expect("vtq area --json prints JSON");
    let structures = json["model"]["structures"].as_array().expect("structures");
    let bytes = |name: &str| {
        structures
            .iter()
            .find(|s| s["name"] == name)
            .unwrap_or_else(|| panic!("no {name} in {json}"))["bytes"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(bytes("treelet count table"), 600 * 31 / 8);
    assert_eq!(bytes("treelet queue table"), 128 * (19 + 32 * 12) / 8);
    assert_eq!(bytes("ray records"), 4096 * 32);
    assert!(json["synthesis"].is_null(), "no synthesis without --synth");
}

/// `vtq area` follows `--set`: 8192 rays need 13-bit ids, 32 KB treelets in a 32-bit address
/// space leave 17-bit treelet addresses, and 8192 ray records of 32 B take 256 KB. Table sizes
/// are accepted although the default mode (baseline) does not simulate the tables.
#[test]
fn area_follows_the_overrides() {
    let text = vtq_ok(&[
        "area",
        "--set",
        "hw.max_rays=8192",
        "--set",
        "hw.treelet_bytes=32768",
        "--set",
        "memory.l1_bytes=65536",
    ]);
    let widths = line_starting(&text, "Widths:");
    assert!(
        widths.contains("treelet address 17 b") && widths.contains("ray id 13 b"),
        "{widths}"
    );
    let rays = line_starting(&text, "ray records          L2");
    assert!(rays.contains(" 8192 ") && rays.contains("256 KB"), "{rays}");
    let text = vtq_ok(&["area", "--set", "hw.count_table_entries=300"]);
    assert_line_contains(&text, "treelet count table  RT unit", " 300 ");
}

#[test]
fn verilog_writes_every_block_and_the_composed_top_lint_clean() {
    let dir = temp_dir("verilog");
    let text = vtq_ok(&["verilog", "--out", dir.to_str().unwrap()]);
    let modules = [
        "treelet_count_table",
        "treelet_queue_table",
        "treelet_controller",
        "rt_unit",
        "rt_datapath",
        "treelet_rt_unit",
        "treelet_rt_unit_wiring",
    ];
    for module in modules {
        let path = dir.join(format!("{module}.v"));
        assert!(text.contains(&path.display().to_string()), "{text}");
        let source = std::fs::read_to_string(&path).unwrap();
        assert!(source.contains(&format!("module {module}")), "{module}");
    }
    let written = std::fs::read_dir(&dir).unwrap().count();
    assert_eq!(written, modules.len(), "only the seven modules are written");
    let files: Vec<_> = modules.iter().map(|m| dir.join(format!("{m}.v"))).collect();
    // Each block alone (the RT unit with its datapath), then the top with everything it
    // instantiates.
    for (module, sources) in [
        ("treelet_count_table", &files[0..1]),
        ("treelet_queue_table", &files[1..2]),
        ("treelet_controller", &files[2..3]),
        ("rt_unit", &files[3..5]),
    ] {
        let lint_dir = dir.join(format!("lint-{module}"));
        std::fs::create_dir_all(&lint_dir).unwrap();
        let Some(report) = or_skip(lint(sources, module, &lint_dir)).unwrap() else {
            return;
        };
        assert!(report.is_clean(), "{module}:\n{report}");
    }
    let lint_dir = dir.join("lint-top");
    std::fs::create_dir_all(&lint_dir).unwrap();
    let Some(report) = or_skip(lint(&files, "treelet_rt_unit", &lint_dir)).unwrap() else {
        return;
    };
    assert!(report.is_clean(), "treelet_rt_unit:\n{report}");
}

/// `vtq cosim --block <block> --scene cornell` with a queues design (ray virtualization and
/// grouping on) for `cycles` cycles, files and waveforms (`--vcd`) kept in `dir`: checks the
/// replay `module` compared every cycle without a mismatch and that its waveforms in
/// `dir/<module>` name their variables alike and name each of `names` ([`assert_same_names`]).
/// Returns the output; `None` when the simulator is missing outside CI.
fn cosim_on_cornell(
    block: &str,
    module: &str,
    cycles: &str,
    dir: &Path,
    names: &[&str],
) -> Option<String> {
    let stdout = cosim_in(
        dir,
        cycles,
        &["--block", block, "--scene", "cornell", "--vcd"],
        &[
            "mode.kind=queues",
            "mode.virtualization=true",
            "mode.grouping=true",
        ],
    )?;
    assert_all_compared(&stdout, module, cycles);
    assert_same_names(&dir.join(module), names);
    Some(stdout)
}

/// `vtq cosim --block rt-unit`: the RT unit's RTL against the Rust block at the configured
/// (paper) sizes, with the toy datapath, and (`--scene`) on a real run's traffic with the
/// scene's datapath answering from its recorded tests, with both waveforms (`--vcd`).
#[test]
fn cosim_of_the_rt_unit_matches() {
    let dir = temp_dir("cosim-rt");
    let Some(stdout) = cosim_in(&dir, "300", &["--block", "rt-unit"], &[]) else {
        return;
    };
    assert_all_compared(&stdout, "rt_unit", "300");
    assert!(dir.join("rt_unit").join("rt_datapath.v").is_file());
    // --vcd: both waveforms with the replay's ports (the RT unit's and the table's) and the
    // RT unit's registers, named alike.
    let Some(stdout) = cosim_on_cornell(
        "rt-unit",
        "rt_unit_replay",
        "300",
        &dir,
        &[
            "issue_valid",
            "req_valid",
            "dp_valid",
            "fifo_count",
            "lane_status_0_0",
        ],
    ) else {
        return;
    };
    assert_line_contains(
        &stdout,
        "  stimulus: ",
        "real traffic with the scene's datapath: cycles 0..300 of SM 0",
    );
}

/// `vtq cosim --block wiring --scene`: the treelet RT unit's wiring alone against its RTL on
/// the ports of a real run (without `--scene` it says what it needs), and `--block
/// treelet-rt-unit --scene`: the whole composed block on the run's recorded inputs; both with
/// their waveforms (`--vcd`), the Rust one's ports and registers named as in the RTL one.
#[test]
fn cosim_of_the_wiring_matches_on_a_real_run() {
    let dir = temp_dir("cosim-wiring");
    let Some(stdout) = cosim_on_cornell(
        "wiring",
        "treelet_rt_unit_wiring",
        "300",
        &dir,
        &["sm_valid", "rt_issue_ready", "id_count"],
    ) else {
        return;
    };
    assert_line_contains(
        &stdout,
        "  stimulus: ",
        "the wiring's ports in cycles 0..300 of SM 0",
    );
    assert_one_line_error(
        &vtq(&["cosim", "--block", "wiring", "--cycles", "10"]),
        "give --scene",
    );
    // The whole block, composed: the top, its children and the wiring. The composed block's
    // registers are its children's (`<child>_<register>`, a grid's members too) and the
    // wiring's (`glue_<register>`), held one level down in the RTL.
    if cosim_on_cornell(
        "treelet-rt-unit",
        "treelet_rt_unit_replay",
        "200",
        &dir,
        &[
            "sm_valid",
            "dp_valid",
            "rt_lane_status_0_0",
            "ctl_mode",
            "glue_id_count",
        ],
    )
    .is_none()
    {
        return;
    }
    assert!(dir
        .join("treelet_rt_unit_replay")
        .join("treelet_rt_unit_wiring.v")
        .is_file());
}

/// The variables of the scopes `inputs`, `outputs` and `regs` of a VCD's header, as
/// `(scope, name, width)`.
fn vcd_scope_vars(path: &Path) -> BTreeSet<(String, String, String)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut scopes: Vec<String> = Vec::new();
    let mut vars = BTreeSet::new();
    for line in text
        .lines()
        .take_while(|l| !l.starts_with("$enddefinitions"))
    {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.first() {
            Some(&"$scope") if t.len() > 2 => scopes.push(t[2].to_string()),
            Some(&"$upscope") => {
                scopes.pop();
            }
            Some(&"$var") if t.len() > 4 => {
                if let Some(s) = scopes
                    .last()
                    .filter(|s| ["inputs", "outputs", "regs"].contains(&s.as_str()))
                {
                    vars.insert((s.clone(), t[4].to_string(), t[2].to_string()));
                }
            }
            _ => {}
        }
    }
    vars
}

/// A co-simulation directory's `rust.vcd` names every variable of its scopes `inputs`,
/// `outputs` and `regs` as `rtl.vcd` does (same scope, name and width), and names each of
/// `expected`.
fn assert_same_names(dir: &Path, expected: &[&str]) {
    let rtl = vcd_scope_vars(&dir.join("rtl.vcd"));
    let rust = vcd_scope_vars(&dir.join("rust.vcd"));
    let missing: Vec<_> = rust.difference(&rtl).take(5).collect();
    assert!(
        missing.is_empty(),
        "{}: in rust.vcd only: {missing:?}",
        dir.display()
    );
    for name in expected {
        assert!(
            rust.iter().any(|(_, n, _)| n == name),
            "{}: rust.vcd has no {name}",
            dir.display()
        );
    }
}

#[test]
fn cosim_matches_on_a_small_configuration() {
    let dir = temp_dir("cosim");
    let Some(stdout) = cosim_in(
        &dir,
        "3000",
        &["--vcd"],
        &[
            "hw.count_table_entries=16",
            "hw.queue_table_entries=8",
            "hw.max_rays=64",
            "hw.underpopulation_threshold=8",
        ],
    ) else {
        return;
    };
    for (module, ports) in [
        ("treelet_count_table", ["op_treelet", "evict_valid"]),
        ("treelet_queue_table", ["op_ray", "spill_valid"]),
    ] {
        assert_all_compared(&stdout, module, "3000");
        assert!(dir.join(module).join(format!("{module}.v")).is_file());
        // --vcd: both waveforms, with the port names in the scopes inputs and outputs.
        let rtl = std::fs::read_to_string(dir.join(module).join("rtl.vcd")).expect("rtl.vcd");
        let rust = std::fs::read_to_string(dir.join(module).join("rust.vcd")).expect("rust.vcd");
        for vcd in [&rtl, &rust] {
            for scope in ["inputs", "outputs", "regs"] {
                assert!(vcd.contains(&format!(" {scope} $end")), "{module}: {scope}");
            }
            for port in ports {
                assert!(vcd.contains(&format!(" {port} ")), "{module}: {port}");
            }
        }
        assert!(rtl.contains("$scope module dut $end"), "{module}");
        assert!(
            rtl.contains("#30020"),
            "{module}: cycle 2999 at 10 (2999 + 2) ns"
        );
    }
    assert!(stdout.contains("waveforms: "), "{stdout}");
    assert!(!stdout.contains("first mismatch"), "{stdout}");
}

/// `vtq area --synth` synthesizes every block with complete RTL and prices it in NAND2
/// equivalents beside the storage model, the RT unit's control and datapath and the treelet
/// hardware's overhead over the whole RT unit; with `--work-dir` a second run reuses every
/// synthesis (small configuration: a minute).
#[test]
fn area_synth_prices_every_block_with_rtl() {
    let dir = temp_dir("area-synth");
    let work_dir = dir.to_str().unwrap();
    let small = [
        "--set",
        "hw.count_table_entries=4",
        "--set",
        "hw.queue_table_entries=6",
        "--set",
        "hw.max_rays=64",
        "--set",
        "hw.underpopulation_threshold=5",
        "--set",
        "hw.repack_threshold=3",
        "--set",
        "hw.warp_size=4",
        "--set",
        "gpu.warp_size=4",
        "--set",
        "gpu.max_ctas_per_sm=2",
        "--set",
        "hw.stack_depth=4",
        "--set",
        "bvh.width=4",
    ];
    let args = |extra: &[&'static str]| {
        let mut a = vec!["area", "--synth", "--work-dir", work_dir];
        a.extend_from_slice(extra);
        a.extend_from_slice(&small);
        a
    };
    let out = vtq(&args(&["--json"]));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let missing = stderr.contains("yosys is not installed");
    if !out.status.success() && missing && std::env::var_os(CI_ENV).is_none() {
        eprintln!("skipping: {}", stderr.trim());
        return;
    }
    assert!(out.status.success(), "{stdout}{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    let s = &json["synthesis"];
    let blocks = s["blocks"].as_array().expect("blocks");
    let names: Vec<&str> = blocks
        .iter()
        .map(|b| b["synth"]["top"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "treelet_count_table",
            "treelet_queue_table",
            "treelet_controller",
            "treelet_rt_unit_wiring"
        ]
    );
    for b in blocks {
        let ffs = b["synth"]["flip_flops"].as_u64().unwrap();
        let eq = b["logic"]["nand2_eq"].as_f64().unwrap();
        assert!(ffs > 0 && eq > ffs as f64 * 17.0 / 3.0, "{b}");
        assert_eq!(b["logic"]["unpriced"], serde_json::json!({}), "{b}");
    }
    assert!(blocks[1]["sram_bits"].as_u64().unwrap() > 0);
    // The RT unit's control: four lanes' registers and stacks, no datapath cells left.
    let rt = &s["rt_unit_logic"];
    assert_eq!(rt["synth"]["top"], "rt_unit");
    assert_eq!(rt["synth"]["latches"], 0, "{rt}");
    assert_eq!(rt["synth"]["warnings"], serde_json::json!([]), "{rt}");
    assert!(
        rt["synth"]["flip_flops"].as_u64().unwrap() > 4 * (256 + 128 + 1024),
        "{rt}"
    );
    assert_eq!(rt["logic"]["unpriced"], serde_json::json!({}), "{rt}");
    let total = s["total_nand2_eq"].as_f64().unwrap();
    let rt_eq = rt["logic"]["nand2_eq"].as_f64().unwrap();
    assert_eq!(s["overhead"].as_f64().unwrap(), total / rt_eq);
    assert!(s["rt_unit"]
        .as_str()
        .unwrap()
        .contains("priced from a published datapath"));
    assert_eq!(s["datapath"]["units"], 4, "one datapath per lane");
    let share = s["proposal_over_rt_unit"].as_f64().unwrap();
    assert!(share > 0.0 && share < s["treelet_over_rt_unit"].as_f64().unwrap());
    assert!(s["paper"].as_str().unwrap().contains("2.2 KB"));
    // The work directory keeps every synthesis: the second run reuses them all.
    let text = vtq_ok(&args(&[]));
    assert_eq!(text.matches("(reused)").count(), 5, "{text}");
    let line = format!(
        "treelet proposal over the whole RT unit: at most {:.1}%",
        100.0 * share
    );
    assert!(text.contains(&line), "{line}\n{text}");
    // Without --synth the option is an error naming it.
    let bad = vtq(&["area", "--work-dir", work_dir]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--synth"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn cosim_of_the_controller_matches_on_a_small_configuration() {
    let dir = temp_dir("cosim-controller");
    let Some(stdout) = cosim_in(
        &dir,
        "2000",
        &["--block", "controller"],
        &[
            "hw.count_table_entries=4",
            "hw.queue_table_entries=6",
            "hw.max_rays=64",
            "hw.underpopulation_threshold=8",
            "hw.divergence_threshold=2",
        ],
    ) else {
        return;
    };
    assert_all_compared(&stdout, "treelet_controller", "2000");
    assert!(stdout.contains("modes: initial"), "{stdout}");
    assert!(
        !stdout.contains("treelet_count_table"),
        "only the controller: {stdout}"
    );
}

/// `vtq cosim --scene`: a real run's table and controller traffic, with waves of rays that end
/// with counts left in the count table (tiny tables, a small cornell frame), replayed against
/// the RTL; the summaries count the count table's clears.
#[test]
fn cosim_replays_a_real_runs_clears() {
    let dir = temp_dir("cosim-scene");
    let sets = [
        "gpu.sms=2",
        "width=32",
        "height=32",
        "memory.l1_bytes=4096",
        "memory.l2_bytes=16384",
        "hw.treelet_bytes=2048",
        "bvh.treelet_formation=breadth_first",
        "hw.divergence_threshold=2",
        "hw.underpopulation_threshold=8",
        "hw.count_table_entries=2",
        "hw.queue_table_entries=2",
    ];
    for (block, module, clears) in [
        ("tables", "treelet_count_table", " clears, "),
        ("controller", "treelet_controller", " count-table clears"),
    ] {
        let args = ["--scene", "cornell", "--config", "vtq", "--block", block];
        let Some(stdout) = cosim_in(&dir, "30000", &args, &sets) else {
            return;
        };
        assert_all_compared(&stdout, module, "30000");
        let summary = stdout
            .lines()
            .find(|l| l.contains(clears))
            .unwrap_or_else(|| panic!("{stdout}"));
        let n: u64 = summary
            .split(clears)
            .next()
            .and_then(|before| before.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{summary}"));
        assert!(n > 0, "no clear replayed: {summary}");
    }
}

#[test]
fn hardware_commands_reject_bad_configurations_in_one_line() {
    let dir = temp_dir("bad-hw-config");
    let out_dir = dir.to_str().unwrap();
    for command in [
        &["area"][..],
        &["verilog", "--out", out_dir],
        &["cosim", "--cycles", "10"],
    ] {
        for (set, key) in [
            ("hw.repack_threshold=33", "hw.repack_threshold"),
            ("hw.no_such_key=1", "no_such_key"),
        ] {
            let mut args = command.to_vec();
            args.extend(["--set", set]);
            assert_one_line_error(&vtq(&args), key);
        }
    }
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "nothing written"
    );
}

/// `vtq sim --ctas` writes every CTA of the frame once, on the SM the round-robin fill gave it
/// while slots last, with spans inside the run; the statistics do not change.
#[test]
fn sim_writes_when_each_cta_ran() {
    let dir = temp_dir("ctas");
    let (plain, with) = (dir.join("plain.json"), dir.join("with.json"));
    let csv = dir.join("ctas.csv");
    let base = [
        "sim",
        "--scene",
        "cornell",
        "--set",
        "width=64",
        "--set",
        "height=32",
    ];
    let mut args = base.to_vec();
    args.extend(["--out", plain.to_str().unwrap()]);
    vtq_ok(&args);
    let mut args = base.to_vec();
    args.extend([
        "--out",
        with.to_str().unwrap(),
        "--ctas",
        csv.to_str().unwrap(),
    ]);
    vtq_ok(&args);
    let stats = |p: &PathBuf| -> serde_json::Value {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        for key in ["sim_wall_seconds", "simulated_rays_per_second"] {
            v.as_object_mut().unwrap().remove(key);
        }
        v
    };
    assert_eq!(stats(&plain), stats(&with));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("cta,sm,start,end"));
    let rows: Vec<[u64; 4]> = lines
        .map(|l| {
            let v: Vec<u64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    // 64 x 32 pixels in 8 x 8 tiles: 32 CTAs, in CTA order.
    assert_eq!(
        rows.iter().map(|r| r[0]).collect::<Vec<_>>(),
        (0..32).collect::<Vec<_>>()
    );
    let cycles = stats(&plain)["cycles"].as_u64().unwrap();
    let sms = 16; // the default GPU
    for [cta, sm, start, end] in &rows {
        assert!(
            start < end && *end < cycles,
            "CTA {cta}: {start}..{end} of {cycles}"
        );
        // The first CTAs fill an idle GPU round-robin.
        if *cta < sms {
            assert_eq!(*sm, *cta);
        }
    }
    // The run ends the cycle after its last CTA retires.
    assert_eq!(rows.iter().map(|r| r[3]).max(), Some(cycles - 1));
    let _ = std::fs::remove_dir_all(&dir);
}
