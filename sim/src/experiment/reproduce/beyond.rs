//! Figures beyond the paper: design questions the paper's blocks invite, answered with the same
//! runs and charts as its figures. Each has its experiment file in `configs/experiments/`
//! (`ext-*.toml`) and its reading in docs/fidelity.md.

use std::path::Path;

use super::figures::{paper, speedup_bars, Figure, PREFETCH, VTQ};
use super::Results;

/// VTQ with treelet prefetching in its ray-stationary phases (design `vtq-prefetch`).
const VTQ_PREFETCH: &str = "configs/designs/vtq-prefetch/config.toml";
/// VTQ with treelet prefetching in every phase.
const VTQ_PREFETCH_ALL: &str = "configs/designs/vtq-prefetch-all/config.toml";

/// VTQ with treelet prefetching: speedups over the baseline of prefetching alone, VTQ alone and
/// VTQ with the prefetcher watching its rays in the ray-stationary phases or in all.
pub fn vtq_prefetch(r: &Results, out: &Path) -> anyhow::Result<Figure> {
    let (img, table) = speedup_bars(
        r,
        out,
        "ext-vtq-prefetch",
        "VTQ with treelet prefetching: speedup over the baseline",
        &[
            ("treelet prefetching", PREFETCH),
            ("VTQ", VTQ),
            ("VTQ + prefetching (ray-stationary phases)", VTQ_PREFETCH),
            ("VTQ + prefetching (all phases)", VTQ_PREFETCH_ALL),
        ],
        vec![paper("baseline", 1.0)],
    )?;
    Ok(Figure {
        id: "ext-vtq-prefetch".into(),
        title: "Beyond the paper: VTQ with treelet prefetching".into(),
        caption: "Speedup over the baseline of treelet prefetching alone (MICRO 2023), VTQ alone, \
                  and VTQ with the same prefetcher beside its treelet RT unit, watching the rays \
                  in the initial and final ray-stationary phases only or in every phase \
                  (`mode.treelet_prefetch`; the prefetcher also serves VTQ's treelet preloads). \
                  The paper does not evaluate this combination."
            .into(),
        images: vec![img],
        table,
    })
}
