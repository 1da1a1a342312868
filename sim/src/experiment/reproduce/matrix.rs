//! What `vtq reproduce` runs and draws: the experiment matrix ([`points`]: every experiment's
//! points, each distinct run once, the paper's first) and the page's figures from the stored
//! runs ([`draw_figures`]: a figure that cannot be drawn, or that the sampled tier cannot
//! estimate, becomes a note on the page instead of stopping the others).

use std::collections::HashSet;
use std::path::Path;

use anyhow::Context;

use super::figures::{self, Figure};
use super::{
    beyond, cause_g, energy, Experiments, Results, BEYOND_EXPERIMENTS, CAUSE_G_EXPERIMENTS,
    FIGURE_EXPERIMENTS,
};
use crate::experiment::sweep::{Point, PreparedScene};

/// The reproduction's runs: every experiment's points (with `scenes` for its scenes, `set`
/// added to its overrides and the tier of `sample`), each distinct run (scene, configuration,
/// tier) once and labelled by its first experiment; and how many of them the paper's figures
/// (those before cause G's) name first.
pub fn points(
    experiments: &Experiments,
    scenes: &[String],
    set: &[String],
    sample: Option<&str>,
) -> anyhow::Result<(Vec<Point>, usize)> {
    let mut points: Vec<Point> = Vec::new();
    let mut seen = HashSet::new();
    // The paper's experiments first: their scenes are then the first of the prepared scenes,
    // which the paper's figures are drawn over.
    let mut paper_points = 0;
    for name in FIGURE_EXPERIMENTS
        .into_iter()
        .chain(CAUSE_G_EXPERIMENTS)
        .chain(BEYOND_EXPERIMENTS)
    {
        if name == CAUSE_G_EXPERIMENTS[0] {
            paper_points = points.len();
        }
        let mut spec = experiments.load(name, scenes)?;
        spec.set.extend(set.iter().cloned());
        spec.sample = sample.map(str::to_string);
        for p in spec
            .points()
            .with_context(|| format!("experiment {name}"))?
        {
            if seen.insert((p.scene.clone(), p.config.to_toml()?, p.tier)) {
                points.push(Point {
                    index: points.len(),
                    label: format!("{name}: {}", p.label),
                    ..p
                });
            }
        }
    }
    Ok((points, paper_points))
}

/// How many of `scenes` (prepared in the order their points first name them) the points
/// `first` name: they are the first that many.
pub fn prepare_count(scenes: &[PreparedScene], first: &[Point]) -> usize {
    scenes
        .iter()
        .take_while(|s| first.iter().any(|p| p.scene == s.spec))
        .count()
}

/// What a figure needs that the sampled tier does not estimate, for the figures it cannot draw
/// from sampled runs (`None`: it can).
fn not_estimated(id: &str) -> Option<&'static str> {
    match id {
        "fig11" => Some("the miss rate in each tenth of the run"),
        "fig15" | "ext-workload-predictions" => Some("the intersection tests of each phase"),
        "fig17" => Some("the energy model's event counts"),
        _ => None,
    }
}

/// The page's entry for figure `id` (`title`) that a sampled reproduction does not draw because
/// it `needs` a statistic the sampled tier does not estimate ([`not_estimated`]).
fn not_drawn_sampled(id: &str, title: &str, needs: &str) -> Figure {
    Figure {
        id: id.to_string(),
        title: title.to_string(),
        caption: format!(
            "Not drawn: the sampled tier estimates cycles, SIMT efficiency, the BVH L1 miss \
             rate, DRAM bytes and the phases' shares of cycles; this figure needs {needs}. Run \
             `vtq reproduce` without --sample for it."
        ),
        images: Vec::new(),
        table: Default::default(),
    }
}

/// Figure `id` (`title`) if it was drawn, else the page's note saying why not, the reason
/// added to `undrawn` (and printed).
pub fn or_note(
    id: &str,
    title: &str,
    figure: anyhow::Result<Figure>,
    undrawn: &mut Vec<String>,
) -> Figure {
    match figure {
        Ok(f) => f,
        Err(e) => {
            let why = format!("{e:#}");
            eprintln!("reproduce: error: {title} was not drawn: {why}");
            undrawn.push(format!("{title}: {why}"));
            Figure {
                id: id.to_string(),
                title: title.to_string(),
                caption: format!("Not drawn: {why}"),
                images: Vec::new(),
                table: Default::default(),
            }
        }
    }
}

/// A figure of the page drawn from the stored runs into the output folder.
type FigureFn = fn(&Results<'_>, &Path) -> anyhow::Result<Figure>;

/// The paper's figures (but Figure 5) drawn from `paper` (its scenes' runs) and the figures on
/// scenes of their own (cause G's, the workload predictions) from `all`, into `out`, in page
/// order; with `sample`, those the sampled tier cannot estimate are notes. Figures that cannot
/// be drawn are notes too, their reasons added to `undrawn` ([`or_note`]).
pub fn draw_figures(
    (paper, all): (&Results<'_>, &Results<'_>),
    out: &Path,
    sample: Option<&str>,
    undrawn: &mut Vec<String>,
) -> Vec<Figure> {
    let paper_figures: [(&str, &str, FigureFn); 10] = [
        ("fig01", "Figure 1", figures::figure1),
        ("fig10", "Figure 10", figures::figure10),
        ("fig11", "Figure 11", figures::figure11),
        ("fig12", "Figure 12", figures::figure12),
        ("fig13", "Figure 13", figures::figure13),
        ("fig14", "Figure 14", figures::figure14),
        ("fig15", "Figure 15", figures::figure15),
        ("fig16", "Figure 16", figures::figure16),
        ("fig17", "Figure 17", energy::figure17),
        (
            "ext-vtq-prefetch",
            "VTQ with treelet prefetching",
            beyond::vtq_prefetch,
        ),
    ];
    let own_scenes: [(&str, &str, FigureFn); 3] = [
        (
            "cause-g-mechanisms",
            "Cause G: which mechanism carries VTQ's gain",
            cause_g::mechanisms,
        ),
        (
            "cause-g-map",
            "Cause G: when the treelet-stationary phase pays",
            cause_g::treelet_map,
        ),
        (
            "ext-workload-predictions",
            "The paper's workload predictions",
            beyond::workload_predictions,
        ),
    ];
    let runs =
        (paper_figures.iter().map(|f| (f, paper))).chain(own_scenes.iter().map(|f| (f, all)));
    runs.map(|((id, title, draw), r)| match (sample, not_estimated(id)) {
        (Some(_), Some(needs)) => not_drawn_sampled(id, title, needs),
        _ => or_note(id, title, draw(r, out), undrawn),
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sampled_tier_skips_only_the_figures_it_cannot_estimate() {
        assert_eq!(not_estimated("fig10"), None);
        assert!(not_estimated("fig15").is_some());
        let note = not_drawn_sampled("fig11", "Figure 11", "x");
        assert!(note.caption.starts_with("Not drawn:") && note.images.is_empty());
        let mut undrawn = Vec::new();
        let f = or_note("f", "F", Err(anyhow::anyhow!("no runs")), &mut undrawn);
        assert_eq!(undrawn, ["F: no runs"]);
        assert_eq!(f.caption, "Not drawn: no runs");
    }
}
