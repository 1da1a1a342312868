//! `[mode]`: which design is simulated ([`ModeKind`]) and its switches ([`ModeConfig`]), what
//! each design puts beside every SM's RT unit ([`ModeConfig::treelet_queues`],
//! [`ModeConfig::prefetcher`], [`ModeConfig::units`]), and the rules that tie the switches to
//! the design. The engine and the statistics ask these questions instead of matching on the
//! design themselves.

use std::fmt;

use serde::{Deserialize, Serialize};
use vtq_hdl::mode::Mode;
use vtq_hdl::HwConfig;

use super::{invalid, ConfigError, SimConfig};

/// The design being simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModeKind {
    /// The baseline RT unit: ray-stationary traversal in the two-stack treelet order.
    #[default]
    Baseline,
    /// The baseline plus the treelet prefetcher of Chou et al. (MICRO 2023).
    Prefetch,
    /// Treelet queues (paper sections 3 and 4), with the switches of [`ModeConfig`].
    Queues,
}

impl ModeKind {
    /// The name used in configuration files.
    pub fn name(self) -> &'static str {
        match self {
            ModeKind::Baseline => "baseline",
            ModeKind::Prefetch => "prefetch",
            ModeKind::Queues => "queues",
        }
    }
}

impl fmt::Display for ModeKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `[mode]`: the design and its feature switches. A switch that means nothing for the chosen
/// `kind` is rejected by validation rather than ignored. Warp repacking is switched by
/// `hw.repack_threshold` (0 = off), not here.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModeConfig {
    /// The design: `baseline`, `prefetch` or `queues`.
    pub kind: ModeKind,
    /// Ray virtualization (section 3.1): a CTA is suspended once all its threads have issued
    /// their rays, freeing its slot for a new CTA, up to `hw.max_rays` rays in flight per SM.
    pub virtualization: bool,
    /// Group underpopulated treelet queues into ray-stationary warps (section 4.4); `queues`
    /// only. Off is the naive treelet-queue design.
    pub grouping: bool,
    /// Preload the next treelet and its rays while the current one drains (section 4.3);
    /// `queues` only.
    pub preload: bool,
    /// Treelet prefetcher policy: prefetch the most popular next treelet once it holds at least
    /// this fraction of the RT unit's rays (Chou et al., MICRO 2023: 0.75); `prefetch`, or
    /// `queues` with `treelet_prefetch` on.
    pub prefetch_threshold: f64,
    /// The treelet prefetcher beside the treelet RT unit too, watching its rays in some
    /// phases (VTQ with treelet prefetching, design `vtq-prefetch`); `queues` only.
    pub treelet_prefetch: TreeletPrefetch,
    /// SM warps enter the RT unit in treelet-stationary mode too (default `true`, as vtq reads
    /// section 4: only the final ray-stationary phase keeps them out). `false`, `queues`
    /// only, keeps them waiting while the controller is treelet stationary: an experiment on
    /// what that phase processes (docs/fidelity.md, Figure 15).
    pub admit_in_treelet_stationary: bool,
}

impl Default for ModeConfig {
    fn default() -> Self {
        ModeConfig {
            kind: ModeKind::Baseline,
            virtualization: false,
            grouping: false,
            preload: false,
            prefetch_threshold: 0.75,
            treelet_prefetch: TreeletPrefetch::Off,
            admit_in_treelet_stationary: true,
        }
    }
}

/// In which phases of the treelet RT unit the treelet prefetcher (Chou et al., MICRO 2023)
/// watches its rays and prefetches the most popular next treelet (`mode.treelet_prefetch`).
/// It shares the prefetcher that serves VTQ's treelet preloads: one queue of sectors, one
/// history of recently queued treelets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TreeletPrefetch {
    /// No popularity prefetching: VTQ as the paper evaluates it.
    #[default]
    Off,
    /// In the ray-stationary phases (initial and final, paper section 3.2), where warps
    /// traverse as in the baseline and the prefetcher's popularity rule applies as designed.
    RayStationary,
    /// In every phase, treelet stationary included.
    All,
}

impl TreeletPrefetch {
    /// The name used in configuration files.
    pub fn name(self) -> &'static str {
        match self {
            TreeletPrefetch::Off => "off",
            TreeletPrefetch::RayStationary => "ray_stationary",
            TreeletPrefetch::All => "all",
        }
    }

    /// Whether the prefetcher watches the RT unit's rays while the controller is in `mode`.
    pub fn watches(self, mode: Mode) -> bool {
        match self {
            TreeletPrefetch::Off => false,
            TreeletPrefetch::RayStationary => {
                matches!(mode, Mode::Initial | Mode::FinalRayStationary)
            }
            TreeletPrefetch::All => true,
        }
    }
}

impl fmt::Display for TreeletPrefetch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl ModeConfig {
    /// Whether each SM's RT unit is the treelet RT unit (controller, count table and queue
    /// table beside the RT unit, `hdl/src/treelet_rt_unit/`).
    pub fn treelet_queues(&self) -> bool {
        self.kind == ModeKind::Queues
    }

    /// Whether each SM has a treelet prefetcher (`sim/src/model/gpu/prefetch.rs`): the prefetch
    /// design's, or beside the treelet RT unit serving its preloads and, with
    /// `treelet_prefetch`, watching its rays.
    pub fn prefetcher(&self) -> bool {
        match self.kind {
            ModeKind::Baseline => false,
            ModeKind::Prefetch => true,
            ModeKind::Queues => self.preload || self.treelet_prefetch != TreeletPrefetch::Off,
        }
    }

    /// Whether the treelet prefetcher's popularity rule runs (the prefetch design's prefetcher,
    /// or the one beside the treelet RT unit with `treelet_prefetch` on), so that
    /// `prefetch_threshold` means something.
    pub fn popularity_prefetch(&self) -> bool {
        self.kind == ModeKind::Prefetch || self.treelet_prefetch != TreeletPrefetch::Off
    }

    /// The design's own units beside each SM's RT unit, as the statistics' `units` list names
    /// them (docs/stats.md).
    pub fn units(&self) -> Vec<&'static str> {
        let mut units = Vec::new();
        if self.treelet_queues() {
            units.extend([
                "treelet_controller",
                "treelet_count_table",
                "treelet_queue_table",
            ]);
            if self.preload {
                units.push("treelet_preloader");
            }
        }
        if self.popularity_prefetch() {
            units.push("prefetcher");
        }
        if self.virtualization {
            units.push("virtualization");
        }
        units
    }
}

impl SimConfig {
    /// Checks the mode's switches against its kind, and the queue features against each other.
    pub(super) fn validate_mode(&self) -> Result<(), ConfigError> {
        self.validate_shared_switches()?;
        if self.mode.kind == ModeKind::Queues {
            self.validate_queue_features()
        } else {
            self.validate_no_queue_keys()
        }
    }

    /// The switches every kind has: ray virtualization's keys and the prefetch threshold.
    fn validate_shared_switches(&self) -> Result<(), ConfigError> {
        let m = &self.mode;
        let kind = m.kind;
        if !m.virtualization {
            if let Some((key, value)) = self.virtualization.changed_key() {
                return Err(invalid(
                    key,
                    value,
                    "only ray virtualization uses it, and mode.virtualization is false",
                ));
            }
        }
        let t = m.prefetch_threshold;
        if !(t.is_finite() && t > 0.0 && t <= 1.0) {
            return Err(invalid(
                "mode.prefetch_threshold",
                t,
                "must be a fraction in (0, 1]",
            ));
        }
        if !m.popularity_prefetch() && t != ModeConfig::default().prefetch_threshold {
            return Err(invalid(
                "mode.prefetch_threshold",
                t,
                format!(
                    "only the treelet prefetcher uses it, and mode.kind is \"{kind}\"{}",
                    if kind == ModeKind::Queues {
                        " with mode.treelet_prefetch = \"off\""
                    } else {
                        ""
                    }
                ),
            ));
        }
        Ok(())
    }

    /// A design without treelet queues: no queue switch or queue-hardware key away from its
    /// default.
    fn validate_no_queue_keys(&self) -> Result<(), ConfigError> {
        let m = &self.mode;
        let kind = m.kind;
        if m.treelet_prefetch != TreeletPrefetch::Off {
            return Err(invalid(
                "mode.treelet_prefetch",
                m.treelet_prefetch,
                format!(
                    "only treelet queues use it (the prefetch design's prefetcher always \
                     runs), and mode.kind is \"{kind}\""
                ),
            ));
        }
        for (key, on) in [
            ("mode.grouping", m.grouping),
            ("mode.preload", m.preload),
            ("rt.queued_stack_traffic", self.rt.queued_stack_traffic),
        ] {
            if on {
                return Err(invalid(
                    key,
                    on,
                    format!("only treelet queues use it, and mode.kind is \"{kind}\""),
                ));
            }
        }
        if self.rt.ray_record_latency != 0 {
            return Err(invalid(
                "rt.ray_record_latency",
                self.rt.ray_record_latency,
                format!(
                    "only treelet queues hold ray records (0 keeps them in memory), and \
                     mode.kind is \"{kind}\""
                ),
            ));
        }
        if !m.admit_in_treelet_stationary {
            return Err(invalid(
                "mode.admit_in_treelet_stationary",
                false,
                format!(
                    "only treelet queues have a treelet-stationary mode, and mode.kind is \
                     \"{kind}\""
                ),
            ));
        }
        let hw = &self.hw;
        let d = HwConfig::default();
        let queue_only = [
            (
                "count_table_entries",
                hw.count_table_entries,
                d.count_table_entries,
            ),
            (
                "queue_table_entries",
                hw.queue_table_entries,
                d.queue_table_entries,
            ),
            (
                "underpopulation_threshold",
                hw.underpopulation_threshold,
                d.underpopulation_threshold,
            ),
            ("repack_threshold", hw.repack_threshold, d.repack_threshold),
            (
                "max_resident_treelets",
                hw.max_resident_treelets,
                d.max_resident_treelets,
            ),
            (
                "divergence_threshold",
                hw.divergence_threshold,
                d.divergence_threshold,
            ),
            (
                "preload_threshold_warps",
                hw.preload_threshold_warps,
                d.preload_threshold_warps,
            ),
            (
                "record_bytes_per_cycle",
                hw.record_bytes_per_cycle,
                d.record_bytes_per_cycle,
            ),
        ];
        for (key, value, default) in queue_only {
            if value != default {
                return Err(invalid(
                    &format!("hw.{key}"),
                    value,
                    format!(
                        "only the treelet-queue hardware uses it, and mode.kind is \
                         \"{kind}\" (leave it at {default} or set mode.kind = \"queues\")"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A treelet-queue design: its features against each other and the L1.
    fn validate_queue_features(&self) -> Result<(), ConfigError> {
        let m = &self.mode;
        let hw = &self.hw;
        if hw.repack_threshold > 0 && !m.grouping {
            return Err(invalid(
                "hw.repack_threshold",
                hw.repack_threshold,
                "warp repacking refills warps from the grouped underpopulated queues (paper \
                 section 4.5), so it needs mode.grouping = true; 0 disables repacking",
            ));
        }
        if hw.repack_threshold > 0 && !m.virtualization {
            return Err(invalid(
                "hw.repack_threshold",
                hw.repack_threshold,
                "warp repacking fetches new rays from memory, which needs ray virtualization \
                 (mode.virtualization = true, paper section 4.5); 0 disables repacking",
            ));
        }
        if !m.preload && hw.preload_threshold_warps != HwConfig::default().preload_threshold_warps {
            return Err(invalid(
                "hw.preload_threshold_warps",
                hw.preload_threshold_warps,
                "only preloading uses it, and mode.preload is false",
            ));
        }
        if m.preload && hw.max_resident_treelets < 2 {
            return Err(invalid(
                "hw.max_resident_treelets",
                hw.max_resident_treelets,
                "preloading (mode.preload = true) needs room for a second resident treelet",
            ));
        }
        let resident = hw.max_resident_treelets as u64 * hw.treelet_bytes as u64;
        if resident > self.memory.l1_bytes as u64 {
            return Err(invalid(
                "hw.max_resident_treelets",
                hw.max_resident_treelets,
                format!(
                    "{} resident treelets of hw.treelet_bytes = {} need {resident} bytes, more \
                     than the L1 (memory.l1_bytes = {})",
                    hw.max_resident_treelets, hw.treelet_bytes, self.memory.l1_bytes
                ),
            ));
        }
        Ok(())
    }
}
