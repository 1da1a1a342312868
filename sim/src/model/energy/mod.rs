//! The energy model (docs/energy.md): it observes a run's statistics and never changes the
//! simulation. Energy = time-proportional power x time + the sum over events of count x energy
//! per event, AccelWattch's structure (energy-sources.md):
//!
//! - time terms: the chip's constant power and its static power x the active-SM fraction, both
//!   scaled from AccelWattch's 80-SM QV100 to `gpu.sms` SMs, plus an idle-SM power per idle SM;
//! - events ([`EnergyEvents`]): L1, L2, interconnect and DRAM accesses, box and triangle tests,
//!   the treelet tables' accesses, with CTA-state traffic (ray virtualization) kept apart.
//!
//! [`evaluate`] is the model, linear in every event count and in time; [`EnergyReport::of_stats`]
//! derives its inputs from statistics JSON (`vtq sim`'s, or any stored run's) and evaluates it.

mod coefficients;
mod events;

use serde::{Deserialize, Serialize};

pub use coefficients::{Coefficients, Term, REFERENCE_SMS};
pub use events::{EnergyEvents, MemoryEvents, TimeInputs};

use crate::model::config::SimConfig;
use events::StatsView;

/// Picojoules per millijoule.
const PJ_PER_MJ: f64 = 1e9;

/// Energy by component, in mJ per frame; they add up to the total.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Components {
    /// Time-proportional: constant, static and idle-SM power times the frame's time.
    pub time: f64,
    /// L1 reads and writes (prefetch lookups included), CTA state excluded.
    pub l1: f64,
    /// L2 reads and writes and the L1-L2 interconnect flits, CTA state excluded.
    pub l2_interconnect: f64,
    /// DRAM reads and writes, CTA state's share excluded.
    pub dram: f64,
    /// Ray-box and ray-triangle tests.
    pub rt_tests: f64,
    /// Treelet count table and queue table accesses.
    pub treelet_tables: f64,
    /// CTA-state saves and restores of ray virtualization: their L2, interconnect and DRAM
    /// events.
    pub virtualization: f64,
}

impl Components {
    /// The sum of the components.
    pub fn total(&self) -> f64 {
        self.time
            + self.l1
            + self.l2_interconnect
            + self.dram
            + self.rt_tests
            + self.treelet_tables
            + self.virtualization
    }

    /// The components with their names, in report order.
    pub fn named(&self) -> [(&'static str, f64); 7] {
        [
            ("time", self.time),
            ("l1", self.l1),
            ("l2_interconnect", self.l2_interconnect),
            ("dram", self.dram),
            ("rt_tests", self.rt_tests),
            ("treelet_tables", self.treelet_tables),
            ("virtualization", self.virtualization),
        ]
    }
}

/// The time-proportional energy split by term, mJ per frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TimeSplit {
    /// Constant power x time.
    pub constant: f64,
    /// Static power x active-SM fraction x time.
    pub static_power: f64,
    /// Idle-SM power x idle SMs x time.
    pub idle_sms: f64,
}

/// The energy of one frame (the statistics' `energy` object; docs/stats.md).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EnergyReport {
    /// The coefficient set used (`energy.coefficients`).
    pub coefficients: String,
    /// Energy of the frame, mJ.
    pub total_mj: f64,
    /// Seconds of the frame (cycles / `energy.clock_mhz`).
    pub seconds: f64,
    /// Average power, W: `total_mj / 1000 / seconds`.
    pub average_power_w: f64,
    /// Energy per ray traced, nJ.
    pub nj_per_ray: f64,
    /// Energy-delay product, J x s.
    pub edp_j_s: f64,
    /// Share of the total that is time-proportional (`components.time / total_mj`).
    pub time_share: f64,
    /// Share of the total that is ray virtualization's CTA-state traffic.
    pub virtualization_share: f64,
    /// Fraction of SM-cycles in which an SM held work.
    pub active_sm_fraction: f64,
    /// Energy by component, mJ.
    pub components: Components,
    /// The time-proportional component by term, mJ.
    pub time_split: TimeSplit,
}

impl EnergyReport {
    /// The report of statistics JSON `stats` (a `vtq sim` output or a stored run's `stats`)
    /// under `cfg` (its sizes, clock and `energy.coefficients`).
    pub fn of_stats(stats: &serde_json::Value, cfg: &SimConfig) -> Result<EnergyReport, String> {
        EnergyReport::of_stats_with(stats, cfg, &Coefficients::of(cfg.energy.coefficients, cfg))
    }

    /// The report of `stats` under `cfg` with the coefficients `c`.
    pub fn of_stats_with(
        stats: &serde_json::Value,
        cfg: &SimConfig,
        c: &Coefficients,
    ) -> Result<EnergyReport, String> {
        let view = StatsView::of(stats)
            .map_err(|e| format!("the statistics lack what the energy model reads: {e}"))?;
        Ok(evaluate(&view.events(cfg), &view.time(cfg), view.rays, c))
    }
}

/// The configuration a statistics JSON recorded (its `config` key), for evaluating stored runs.
pub fn stats_config(stats: &serde_json::Value) -> Result<SimConfig, String> {
    let text = stats
        .get("config")
        .and_then(|v| v.as_str())
        .ok_or("the statistics have no `config` (the run's configuration as TOML)")?;
    SimConfig::load_str(std::path::Path::new("the statistics' config"), text, &[])
        .map_err(|e| e.to_string())
}

/// The model: the energy of a frame with `events`, `time` and `rays` under coefficients `c`.
/// Linear in every event count; the time terms depend only on `time`.
pub fn evaluate(
    events: &EnergyEvents,
    time: &TimeInputs,
    rays: u64,
    c: &Coefficients,
) -> EnergyReport {
    let mj = |pj: f64| pj / PJ_PER_MJ;
    let scale = time.sms / REFERENCE_SMS;
    let idle_sms = time.sms * (1.0 - time.active_sm_fraction);
    let time_split = TimeSplit {
        constant: c.get(Term::ConstantW) * scale * time.seconds * 1e3,
        static_power: c.get(Term::StaticW) * scale * time.active_sm_fraction * time.seconds * 1e3,
        idle_sms: c.get(Term::IdleSmW) * idle_sms * time.seconds * 1e3,
    };
    let (l1, l2, dram) = memory_pj(&events.memory, c);
    let (v1, v2, vd) = memory_pj(&events.cta_state, c);
    let components = Components {
        time: time_split.constant + time_split.static_power + time_split.idle_sms,
        l1: mj(l1),
        l2_interconnect: mj(l2),
        dram: mj(dram),
        rt_tests: mj(events.box_tests * c.get(Term::BoxTest)
            + events.triangle_tests * c.get(Term::TriangleTest)),
        treelet_tables: mj(events.count_table_searches * c.get(Term::CountTableSearch)
            + events.count_table_writes * c.get(Term::CountTableWrite)
            + events.count_table_reads * c.get(Term::CountTableRead)
            + events.queue_table_reads * c.get(Term::QueueTableRead)
            + events.queue_table_writes * c.get(Term::QueueTableWrite)),
        virtualization: mj(v1 + v2 + vd),
    };
    let total = components.total();
    let share = |x: f64| if total > 0.0 { x / total } else { 0.0 };
    EnergyReport {
        coefficients: c.set.name().to_string(),
        total_mj: total,
        seconds: time.seconds,
        average_power_w: if time.seconds > 0.0 {
            total * 1e-3 / time.seconds
        } else {
            0.0
        },
        nj_per_ray: if rays > 0 {
            total * 1e6 / rays as f64
        } else {
            0.0
        },
        edp_j_s: total * 1e-3 * time.seconds,
        time_share: share(components.time),
        virtualization_share: share(components.virtualization),
        active_sm_fraction: time.active_sm_fraction,
        components,
        time_split,
    }
}

/// The L1, L2-and-interconnect and DRAM energy (pJ) of memory events `e`.
fn memory_pj(e: &MemoryEvents, c: &Coefficients) -> (f64, f64, f64) {
    let l1 = e.l1_read_hits * c.get(Term::L1ReadHit)
        + e.l1_read_misses * c.get(Term::L1ReadMiss)
        + e.l1_write_hits * c.get(Term::L1WriteHit)
        + e.l1_write_misses * c.get(Term::L1WriteMiss);
    let l2 = e.l2_read_hits * c.get(Term::L2ReadHit)
        + e.l2_read_misses * c.get(Term::L2ReadMiss)
        + e.l2_write_hits * c.get(Term::L2WriteHit)
        + e.l2_write_misses * c.get(Term::L2WriteMiss)
        + e.flits * c.get(Term::Flit);
    let dram = e.dram_reads * c.get(Term::DramRead) + e.dram_writes * c.get(Term::DramWrite);
    (l1, l2, dram)
}

/// A design's energy relative to a reference design's (the baseline's), with the terms of the
/// identity E = f x T + (1 - f) x D (energy-sources.md, "An identity worth printing").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Relative {
    /// E: the design's energy over the reference's.
    pub energy: f64,
    /// f: the reference's time-proportional share.
    pub time_share: f64,
    /// T: the design's time over the reference's (1 / speedup at one clock).
    pub time: f64,
    /// D: the design's event energy over the reference's.
    pub events: f64,
    /// f x T + (1 - f) x D: equals `energy` when the time-proportional power is the same in
    /// both runs; the active-SM fraction makes it differ slightly otherwise.
    pub identity: f64,
}

impl Relative {
    /// `design` relative to `reference` (ratios are 0 where the reference's term is 0).
    pub fn of(design: &EnergyReport, reference: &EnergyReport) -> Relative {
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        let events = |r: &EnergyReport| r.total_mj - r.components.time;
        let f = reference.time_share;
        let t = ratio(design.seconds, reference.seconds);
        let d = ratio(events(design), events(reference));
        Relative {
            energy: ratio(design.total_mj, reference.total_mj),
            time_share: f,
            time: t,
            events: d,
            identity: f * t + (1.0 - f) * d,
        }
    }
}
