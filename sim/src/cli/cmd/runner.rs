//! Running points of a sweep into the result store, shared by `vtq sweep` and `vtq reproduce`:
//! the scenes the points need, loaded once ([`prepare_scenes`]), and the [`Runner`] that runs
//! the points not yet done with a progress bar and one line per finished run.

use std::io::IsTerminal;

use anyhow::Context;

use super::options::{build_bvh, load_scene, CacheArgs};
use crate::experiment::sweep::run::{run_tasks, Task};
use crate::experiment::sweep::{Point, PreparedScene, ResultStore, Reuse, RunRecord, RunStatus};
use crate::model::bvh::{BvhParams, HwBvh};
use crate::model::scene::Scene;

/// Loads each distinct scene of `points` (printing a summary line each), in order.
pub(crate) fn prepare_scenes<'a>(
    points: impl IntoIterator<Item = &'a Point>,
) -> anyhow::Result<Vec<PreparedScene>> {
    let mut scenes: Vec<PreparedScene> = Vec::new();
    for point in points {
        if !scenes.iter().any(|s| s.spec == point.scene) {
            scenes.push(PreparedScene::new(&point.scene, load_scene(&point.scene)?));
        }
    }
    Ok(scenes)
}

/// The prepared scene of `point`.
pub(crate) fn scene_of<'a>(scenes: &'a [PreparedScene], point: &Point) -> &'a PreparedScene {
    scenes
        .iter()
        .find(|s| s.spec == point.scene)
        .expect("every point's scene was prepared")
}

/// Most labels a message lists before it counts the rest.
const LISTED: usize = 5;

/// The labels of `failed` points for a message: every one when there are few, else the first
/// [`LISTED`] and how many more (each failed run's error is in its result file, and `vtq sweep
/// --collect` tables them all).
pub(crate) fn listed(failed: &[String]) -> String {
    let shown = failed[..failed.len().min(LISTED)].join("; ");
    match failed.len().saturating_sub(LISTED) {
        0 => shown,
        more => format!("{shown}; and {more} more"),
    }
}

/// One line about a finished run.
fn describe(record: &RunRecord) -> String {
    use crate::estimate::sample::stored::{is_sampled, stored_estimate};
    let estimate = |s: &serde_json::Value, name: &str, digits: usize| {
        stored_estimate(s, name).map_or_else(|| "-".into(), |e| e.display(digits))
    };
    match (record.status, record.stats()) {
        (RunStatus::Ok, Some(s)) if is_sampled(s) => format!(
            "ok (sampled, 95% intervals): {} cycles, SIMT efficiency {}, BVH L1 miss rate {} \
             ({:.2} s)",
            estimate(s, "cycles", 0),
            estimate(s, "simt_efficiency", 3),
            estimate(s, "bvh_l1_miss_rate", 3),
            record.wall_seconds
        ),
        (RunStatus::Ok, Some(s)) => format!(
            "ok: {} cycles, SIMT efficiency {:.3}, BVH L1 miss rate {:.3} ({:.2} s)",
            s["cycles"],
            s["simt_efficiency"].as_f64().unwrap_or(f64::NAN),
            s["bvh_l1_miss_rate"].as_f64().unwrap_or(f64::NAN),
            record.wall_seconds
        ),
        _ => format!(
            "FAILED: {}",
            record.error.as_deref().unwrap_or("no error recorded")
        ),
    }
}

/// Runs points into a result store, skipping those already done, with a progress bar on a
/// terminal and one line per finished run (shared by `vtq sweep` and `vtq reproduce`).
pub(crate) struct Runner<'a> {
    /// The command, prefixing every line.
    pub name: &'a str,
    /// Where results are stored and found.
    pub store: &'a ResultStore,
    /// Which stored results count as done.
    pub reuse: Reuse,
    /// Runs at once [default: the available cores].
    pub jobs: Option<u32>,
    /// The BVH build cache.
    pub cache: &'a CacheArgs,
}

impl Runner<'_> {
    /// Runs every point of `selected` (whose scenes are in `scenes`) that has no result in the
    /// store yet; `total` and `slice` describe the selection in the summary line. Returns the
    /// labels of the points whose run failed (now or earlier).
    pub fn run(
        &self,
        selected: &[&Point],
        scenes: &[PreparedScene],
        total: usize,
        slice: &str,
    ) -> anyhow::Result<Vec<String>> {
        let (name, store) = (self.name, self.store);
        // Which points are done: a result file with an ok run (or a failed one, unless retried).
        let mut pending: Vec<&Point> = Vec::new();
        let (mut done, mut failed_before) = (0usize, Vec::new());
        for &point in selected {
            let key = point
                .key(&scene_of(scenes, point).hash)
                .with_context(|| format!("{name} point {}", point.label))?;
            match store.load(&key) {
                Ok(Some(record)) if self.reuse.is_done(&record) => match record.status {
                    RunStatus::Ok => done += 1,
                    RunStatus::Failed => failed_before.push(point.label.clone()),
                },
                Ok(_) => pending.push(point),
                Err(e) => {
                    eprintln!("{name}: warning: {e:#}; running {} again", point.label);
                    pending.push(point);
                }
            }
        }
        let jobs = match self.jobs {
            Some(n) => n as usize,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        let at_a_time = match pending.len() {
            0 => String::new(),
            n => format!(", {} at a time", jobs.min(n)),
        };
        println!(
            "{name}: {total} point{}{slice}; {done} already done, {} failed earlier (skipped; \
             --retry-failed runs them again), {} to run{at_a_time}; results in {}",
            if total == 1 { "" } else { "s" },
            failed_before.len(),
            pending.len(),
            store.runs_dir().display()
        );

        // Build (or load) the BVHs first, so their summaries do not cut through the progress.
        let build = |scene: &Scene, params: &BvhParams| -> anyhow::Result<HwBvh> {
            build_bvh(scene, params, self.cache)
        };
        for point in &pending {
            let scene = scene_of(scenes, point);
            let params = point.config.bvh_params();
            if point.config.validate().is_ok() && !scene.has_bvh(&params) {
                if let Err(e) = scene.bvh(&params, &build) {
                    eprintln!("{name}: {e:#} (its points are recorded as failed)");
                }
            }
        }

        let tasks: Vec<Task> = pending
            .iter()
            .map(|p| Task {
                scene: scene_of(scenes, p),
                config: &p.config,
                tier: p.tier,
            })
            .collect();
        let bar = (std::io::stderr().is_terminal() && !tasks.is_empty()).then(|| {
            let bar = indicatif::ProgressBar::new(tasks.len() as u64);
            let template =
                format!("{name} {{bar:40}} {{pos}}/{{len}} runs {{elapsed}} (eta {{eta}}) {{msg}}");
            bar.set_style(
                indicatif::ProgressStyle::with_template(&template)
                    .expect("the progress template is valid"),
            );
            bar
        });
        let (mut ran, mut failed_now) = (0usize, Vec::new());
        let outcome = run_tasks(store, &tasks, jobs, &build, |i, record| {
            ran += 1;
            if record.status == RunStatus::Failed {
                failed_now.push(pending[i].label.clone());
            }
            let line = format!(
                "{name}: [{ran}/{}] {}: {}",
                tasks.len(),
                pending[i].label,
                describe(record)
            );
            match &bar {
                Some(bar) => {
                    bar.println(line);
                    bar.set_message(format!("last: {}", pending[i].label));
                    bar.inc(1);
                }
                None => println!("{line}"),
            }
        });
        if let Some(bar) = &bar {
            bar.finish_and_clear();
        }
        outcome?;
        println!(
            "{name}: ran {ran} ({} ok, {} failed), skipped {} ({done} done, {} failed earlier); \
             results in {}",
            ran - failed_now.len(),
            failed_now.len(),
            done + failed_before.len(),
            failed_before.len(),
            store.runs_dir().display()
        );
        Ok(failed_before.into_iter().chain(failed_now).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_failure_lists_are_cut_and_counted() {
        let labels: Vec<String> = (0..8).map(|i| format!("p{i}")).collect();
        assert_eq!(listed(&labels[..2]), "p0; p1");
        assert_eq!(listed(&labels[..5]), "p0; p1; p2; p3; p4");
        assert_eq!(listed(&labels), "p0; p1; p2; p3; p4; and 3 more");
    }
}
