//! `vtq render`: load a scene, build (or load the cached) hardware BVH, path trace the LumiBench
//! workload and write the image as a PNG.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::cli::cmd::options::{build_bvh, load_scene, BvhArgs, ImageArgs};
use crate::cli::image::write_png;
use crate::cli::output::{check_file, write_or_keep, Failures};
use crate::model::workload::kind::WorkloadKind;
use crate::model::workload::pathtracer::render;
use crate::model::workload::ray_file::write_ray_file;

/// Options of `vtq render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene: a built-in name (`wknd`, `cornell`, `city:N` e.g. `city:250k`), a folder under
    /// ../shared/scenes, a scene folder path or a `.obj` file (see `vtq scenes`).
    #[arg(long)]
    pub scene: String,
    /// Output PNG file [default: `<scene name>.png` in the current directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write every traced ray (pixel order, then path order) to this file: CSV in the
    /// format `vtq trace --rays` reads (with an `occlusion` column if the workload traces
    /// occlusion rays), or the compact binary form if it ends in `.bin`; either replays with
    /// `--set workload.kind=rays --set workload.rays_file=FILE`.
    #[arg(long)]
    pub rays_out: Option<PathBuf>,
    /// Image size and path limits.
    #[command(flatten)]
    pub image: ImageArgs,
    /// BVH build and cache options.
    #[command(flatten)]
    pub bvh: BvhArgs,
}

/// `<scene name>.png` in the current directory, with characters other than ASCII letters,
/// digits, `-`, `_` and `.` replaced by `_` so that the name stays one plain file name.
fn default_out(scene_name: &str) -> PathBuf {
    let stem: String = scene_name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    PathBuf::from(format!("{stem}.png"))
}

/// Run `vtq render`.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let settings = args.image.settings()?;
    // The outputs are checked before the work (the default image name needs the scene's name,
    // so that one right after loading it).
    for path in args.out.iter().chain(&args.rays_out) {
        check_file(path)?;
    }
    let scene = load_scene(&args.scene)?;
    let out = args.out.clone().unwrap_or_else(|| default_out(&scene.name));
    check_file(&out)?;
    let bvh = build_bvh(&scene, &args.bvh.params(), &args.bvh.cache)?;

    let progress = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(u64::from(settings.height));
        bar.set_style(
            indicatif::ProgressStyle::with_template("render {bar:40} {pos}/{len} rows {elapsed}")
                .expect("the progress template is valid"),
        );
        bar
    });
    let result = render(&scene, &bvh, &settings, progress.as_ref())
        .with_context(|| format!("rendering scene '{}'", scene.name))?;
    if let Some(bar) = &progress {
        bar.finish_and_clear();
    }

    // Every output is attempted; one that cannot be written is kept in a fallback file.
    let mut failures = Failures::default();
    let mut black = 0;
    let wrote_image = failures.note(write_or_keep(&out, |p| {
        write_png(p, result.width, result.height, &result.image).map(|n| black = n)
    }));
    let stats = &result.stats;
    let what = match &settings.kind {
        WorkloadKind::Path => format!("path tracer, {} bounces", settings.bounces),
        WorkloadKind::Hybrid => format!(
            "hybrid: the path tracer's secondary rays, {} bounces, primary hits given",
            settings.bounces
        ),
        WorkloadKind::PathNee => format!(
            "path tracer with next-event estimation, {} bounces ({} shadow rays)",
            settings.bounces, stats.occlusion_rays
        ),
        WorkloadKind::Rays(set) => format!("rays of {}", set.path),
        &WorkloadKind::Ao { rays, radius } => format!(
            "ambient occlusion, {rays} rays per hit of radius {radius} x the scene's diagonal \
             ({} occlusion rays)",
            stats.occlusion_rays
        ),
    };
    println!(
        "render: {}x{}, {} spp, {what}: {} rays in {:.3} s ({:.0} rays/s)",
        settings.width,
        settings.height,
        settings.spp,
        stats.rays_traced,
        stats.wall_seconds,
        stats.rays_traced as f64 / stats.wall_seconds.max(1e-9),
    );
    if stats.nonfinite_samples > 0 || black > 0 {
        println!(
            "warning: {} samples had NaN/inf radiance (written as black); {} pixels written black",
            stats.nonfinite_samples, black
        );
    }
    if wrote_image {
        println!("wrote {}", out.display());
    }
    if let Some(path) = &args.rays_out {
        if failures.note(write_or_keep(path, |p| {
            write_ray_file(p, &result.trace_rays())
        })) {
            println!("wrote {} rays to {}", result.rays.len(), path.display());
        }
    }
    failures.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_out_is_a_plain_file_name() {
        assert_eq!(default_out("SPNZA"), PathBuf::from("SPNZA.png"));
        assert_eq!(default_out("a/b c"), PathBuf::from("a_b_c.png"));
    }
}
