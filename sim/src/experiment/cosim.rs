//! The real traffic a co-simulation replays: one SM's treelet RT unit inputs, recorded cycle by
//! cycle from reset in a simulation of a scene (`vtq cosim --scene`; the replays themselves are
//! built and run by the RTL generator's crate, vtq-gen).

use anyhow::Context;
use vtq_hdl::treelet_rt_unit::TableLog;

use crate::model::bvh::HwBvh;
use crate::model::config::SimConfig;
use crate::model::gpu::{simulate, SimOptions};
use crate::model::scene::Scene;

/// A simulation's recording of one SM's inputs.
#[derive(Debug)]
pub struct Recording {
    /// The SM's recorded inputs, from reset.
    pub log: TableLog,
    /// The run in words: SM and scene.
    pub run: String,
    /// The design and the whole run's cycles in words.
    pub about: String,
}

/// Simulates `scene` (BVH `bvh`) with `cfg` and records SM `sm`'s treelet RT unit inputs in its
/// first `cycles` cycles. An error if the run fails or records nothing (a design without
/// treelet queues: the error says so).
pub fn record_sm(
    scene: &Scene,
    bvh: &HwBvh,
    cfg: &SimConfig,
    sm: usize,
    cycles: usize,
) -> anyhow::Result<Recording> {
    let options = SimOptions {
        record_tables: Some((sm, cycles)),
        ..SimOptions::default()
    };
    let out = simulate(scene, bvh, cfg, options, None)
        .with_context(|| format!("simulating scene '{}'", scene.name))?;
    let log = out
        .table_log
        .context("the simulation recorded no table inputs")?;
    Ok(Recording {
        log,
        run: format!("SM {sm} in scene {}", scene.name),
        about: format!(
            "{}, {} cycles in all",
            cfg.mode.kind.name(),
            out.stats.cycles
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::scene::load::load_scene;

    /// A queues run records every cycle asked for, from reset, for each block; a design
    /// without treelet queues is an error that says what recording needs.
    #[test]
    fn a_queues_run_records_the_cycles_asked_for() {
        let scene = load_scene("cornell").expect("built-in scene");
        let sets = [
            "mode.kind=queues",
            "hw.repack_threshold=0",
            "gpu.sms=2",
            "width=16",
            "height=16",
        ]
        .map(String::from);
        let cfg = SimConfig::load(None, &sets).expect("valid configuration");
        let bvh = HwBvh::build(&scene, &cfg.bvh_params()).expect("BVH builds");
        let rec = record_sm(&scene, &bvh, &cfg, 1, 300).expect("records");
        assert_eq!(rec.log.controller.len(), 300);
        assert_eq!(rec.log.rt_unit.len(), 300);
        assert_eq!(rec.log.treelet.len(), 300);
        assert!(rec.run.starts_with("SM 1 in scene "), "{}", rec.run);
        let sets = ["mode.kind=baseline", "width=16", "height=16"].map(String::from);
        let plain = SimConfig::load(None, &sets).expect("valid configuration");
        let bvh = HwBvh::build(&scene, &plain.bvh_params()).expect("BVH builds");
        let err = record_sm(&scene, &bvh, &plain, 0, 300).unwrap_err();
        assert!(format!("{err:#}").contains("needs mode.kind"), "{err:#}");
    }
}
