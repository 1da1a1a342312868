//! The simulator's configuration ([`SimConfig`]): one TOML file of sections, each parameter
//! documented with its default (the paper's Table 1 GPU, Vulkan-Sim timing, or a stated modelling
//! assumption; docs/config.md lists them all), `--set key=value` overrides, and validation that
//! names the offending key, its value and why it is rejected.
//!
//! # Layers
//! [`SimConfig::load`] starts from [`SimConfig::default`] (the baseline GPU of Table 1), merges
//! the TOML file over it, then applies each `--set` override in order, and finally validates the
//! result. Every key given by the file or an override is checked on its own against the
//! defaults, so an unknown key or a value of the wrong type is reported with its exact dotted
//! name and where it came from.
//!
//! # One place per parameter
//! The RT-unit hardware sizes live in `[hw]` ([`HwConfig`], shared with the hardware models) and
//! are not repeated elsewhere: the treelet size is `hw.treelet_bytes` (the BVH build reads it
//! from there, [`SimConfig::bvh_params`]) and warp repacking is switched by
//! `hw.repack_threshold` (0 = off). The only value held twice is the warp size (`gpu.warp_size`
//! for the SM, `hw.warp_size` for the RT unit), and validation requires the two to agree.

use std::path::Path;

use serde::{Deserialize, Serialize};
use toml::{Table, Value};
use vtq_hdl::controller::ControllerFeatures;
use vtq_hdl::rt_unit::RtUnitParams;
use vtq_hdl::HwConfig;

use crate::model::bvh::BvhParams;
use crate::model::memory::MemConfig;
use crate::model::workload::kind::WorkloadKind;
use crate::model::workload::pathtracer::RenderSettings;

mod energy;
mod error;
mod mode;
mod overrides;
mod sample;
pub mod sample_points;
mod sections;
mod validate;
mod virtualization;
mod workload;

pub use energy::{CoefficientSet, EnergyConfig};
pub use error::ConfigError;
use error::{in_range, invalid, memory_error};
pub use mode::{ModeConfig, ModeKind, TreeletPrefetch};
pub use overrides::parse_override_value;
use overrides::{apply_override, merge, Origin};
pub use sample::{Cluster, SampleConfig};
pub use sections::{BvhConfig, EngineConfig, GpuConfig, RtConfig};
pub use virtualization::{RestorePolicy, SuspendPolicy, VirtualizationConfig};
pub use workload::{WorkloadConfig, WorkloadKindName};

/// Workload keys that `--set` also accepts without their `workload.` prefix (`--set width=64`).
pub const BARE_KEYS: [&str; 4] = ["width", "height", "spp", "bounces"];

/// Bytes of one saved 32-bit value (register, SIMT mask, PC) of a suspended CTA.
const WORD_BYTES: u64 = 4;

/// Saved words per SIMT-stack entry of a suspended warp: active mask, PC, reconvergence PC.
const WORDS_PER_SIMT_ENTRY: u64 = 3;

/// The complete simulator configuration, one field per TOML section.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// `[gpu]`: the SMs, CTA slots, registers and shader timing.
    pub gpu: GpuConfig,
    /// `[memory]`: the L1, L2 and DRAM of the memory system.
    pub memory: MemConfig,
    /// `[rt]`: RT-unit timing not in `[hw]`: intersection latencies and the response path.
    pub rt: RtConfig,
    /// `[hw]`: sizes and thresholds of the treelet-queue hardware (shared with `vtq-hdl`).
    pub hw: HwConfig,
    /// `[mode]`: which design is simulated (baseline, treelet prefetching, treelet queues).
    pub mode: ModeConfig,
    /// `[virtualization]`: how ray virtualization suspends and resumes CTAs (modelling
    /// switches; `mode.virtualization` only).
    pub virtualization: VirtualizationConfig,
    /// `[workload]`: the path-traced image.
    pub workload: WorkloadConfig,
    /// `[bvh]`: the hardware BVH build.
    pub bvh: BvhConfig,
    /// `[sim]`: the simulation engine (watchdog, lockstep verification, time series).
    pub sim: EngineConfig,
    /// `[sample]`: the sampled tier's settings (used only when sampling is asked for).
    pub sample: SampleConfig,
    /// `[energy]`: the energy model's coefficients and clock (observes the statistics; changes
    /// nothing simulated). Written to the TOML only when it differs from its defaults.
    #[serde(skip_serializing_if = "EnergyConfig::is_default")]
    pub energy: EnergyConfig,
}

impl SimConfig {
    /// Reads a configuration: the defaults, then the TOML file at `path` (if any), then each
    /// `--set` override (`key=value`, dotted key; the workload keys also bare), then
    /// [`SimConfig::validate`]. Values are TOML (`16`, `0.75`, `true`, `"queues"`); a value that
    /// is not TOML but starts with a letter is taken as a string, so `mode.kind=queues` works.
    pub fn load(path: Option<&Path>, overrides: &[String]) -> Result<SimConfig, ConfigError> {
        let config = SimConfig::parse(path, overrides)?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a configuration exactly as [`SimConfig::load`] reads the file `origin`, but from
    /// `text` (for configurations built into the binary); `origin` names it in messages.
    pub fn load_str(
        origin: &Path,
        text: &str,
        overrides: &[String],
    ) -> Result<SimConfig, ConfigError> {
        let config = SimConfig::parse_text(Some((origin, text)), overrides)?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a configuration as [`SimConfig::load_str`] does (`file` is the path and text of a
    /// configuration file, `None` for the defaults alone; unknown keys and values of the wrong
    /// type are still errors) but does not [validate](SimConfig::validate) it: `vtq sweep`
    /// records a point whose configuration is out of range as a failed run instead of stopping.
    pub fn load_unvalidated(
        file: Option<(&Path, &str)>,
        overrides: &[String],
    ) -> Result<SimConfig, ConfigError> {
        SimConfig::parse_text(file, overrides)
    }

    /// The defaults, then the file, then the overrides, not validated.
    fn parse(path: Option<&Path>, overrides: &[String]) -> Result<SimConfig, ConfigError> {
        let text = path
            .map(|path| {
                std::fs::read_to_string(path).map_err(|e| ConfigError::Read {
                    path: path.to_path_buf(),
                    reason: e.to_string(),
                })
            })
            .transpose()?;
        SimConfig::parse_text(path.zip(text.as_deref()), overrides)
    }

    /// The defaults, then the configuration text (and the path it came from), then the
    /// overrides, not validated.
    fn parse_text(
        file: Option<(&Path, &str)>,
        overrides: &[String],
    ) -> Result<SimConfig, ConfigError> {
        let defaults = SimConfig::default().to_table()?;
        let mut merged = defaults.clone();
        if let Some((path, text)) = file {
            let file: Table = text
                .parse()
                .map_err(|e: toml::de::Error| ConfigError::Syntax {
                    path: path.to_path_buf(),
                    message: e.to_string().trim_end().to_string(),
                })?;
            merge(
                &defaults,
                &mut merged,
                &file,
                &mut Vec::new(),
                Origin::File(path),
            )?;
        }
        for text in overrides {
            apply_override(&defaults, &mut merged, text)?;
        }
        let mut config: SimConfig = Value::Table(merged)
            .try_into()
            .map_err(|e: toml::de::Error| ConfigError::Toml(e.message().to_string()))?;
        config.workload.read_rays()?;
        Ok(config)
    }

    /// The configuration as a TOML document, every key written out (for echoing the effective
    /// configuration into statistics; [`SimConfig::load`] reads it back unchanged).
    pub fn to_toml(&self) -> Result<String, ConfigError> {
        toml::to_string(self).map_err(|e| ConfigError::Toml(e.to_string()))
    }

    /// The configuration as a TOML table, every key present (also those [`SimConfig::to_toml`]
    /// leaves out at their defaults: `rt.ray_record_latency`, the `[energy]` section): the table
    /// of valid keys that files and overrides are checked against.
    fn to_table(&self) -> Result<Table, ConfigError> {
        let mut table = Table::try_from(self).map_err(|e| ConfigError::Toml(e.to_string()))?;
        if let Some(Value::Table(rt)) = table.get_mut("rt") {
            rt.entry("ray_record_latency")
                .or_insert(Value::Integer(self.rt.ray_record_latency.into()));
        }
        if !table.contains_key("energy") {
            let energy =
                Table::try_from(self.energy).map_err(|e| ConfigError::Toml(e.to_string()))?;
            table.insert("energy".to_string(), Value::Table(energy));
        }
        Ok(table)
    }

    /// The image settings of the workload.
    pub fn render_settings(&self) -> RenderSettings {
        RenderSettings {
            width: self.workload.width,
            height: self.workload.height,
            spp: self.workload.spp,
            bounces: self.workload.bounces,
            kind: match self.workload.kind {
                WorkloadKindName::Path => WorkloadKind::Path,
                WorkloadKindName::PathNee => WorkloadKind::PathNee,
                WorkloadKindName::Hybrid => WorkloadKind::Hybrid,
                WorkloadKindName::Ao => WorkloadKind::Ao {
                    rays: self.workload.ao_rays,
                    radius: self.workload.ao_radius as f32,
                },
                WorkloadKindName::Rays => match &self.workload.rays {
                    Some(set) => WorkloadKind::Rays(set.clone()),
                    // Not reached for a loaded configuration (it read the file).
                    None => WorkloadKind::Path,
                },
            },
        }
    }

    /// The BVH build parameters: `bvh.width` and the treelet size `hw.treelet_bytes`.
    pub fn bvh_params(&self) -> BvhParams {
        BvhParams {
            width: self.bvh.width,
            treelet_bytes: self.hw.treelet_bytes,
            formation: self.bvh.treelet_formation,
        }
    }

    /// The treelet controller's feature switches (`mode.grouping`, `mode.preload`,
    /// `mode.admit_in_treelet_stationary`).
    pub fn controller_features(&self) -> ControllerFeatures {
        ControllerFeatures {
            group_underpopulated: self.mode.grouping,
            preload: self.mode.preload,
            admit_in_treelet_stationary: self.mode.admit_in_treelet_stationary,
        }
    }

    /// The treelet controller's features the hardware tools (`vtq verilog`, `vtq cosim`, `vtq
    /// area`) build it with: a treelet-queue design's own, the full design's otherwise (a design
    /// without a controller still gets one to generate and size).
    pub fn hardware_controller_features(&self) -> ControllerFeatures {
        if self.mode.treelet_queues() {
            self.controller_features()
        } else {
            ControllerFeatures::FULL
        }
    }

    /// The RT unit's parameters, with its hit records placed at `hit_record_base` and its
    /// stack spill area of `stack_spill_chunks` chunks per ray stack at `stack_base` (choices of
    /// the simulator's memory layout, not of the configuration; `None`: at the top of the
    /// address space). The stack room kept free before a fetch is the BVH width.
    pub fn rt_unit_params(
        &self,
        hit_record_base: u64,
        stack_base: Option<u64>,
        stack_spill_chunks: u32,
    ) -> RtUnitParams {
        RtUnitParams {
            latencies: self.rt.latencies,
            resp_fifo_depth: self.rt.resp_fifo_depth,
            resp_ports: self.rt.resp_ports,
            hit_record_base,
            max_children: self.bvh.width,
            stack_base,
            stack_spill_chunks,
        }
    }

    /// Warps of one raygen CTA.
    pub fn warps_per_cta(&self) -> u32 {
        self.gpu.threads_per_cta.div_ceil(self.gpu.warp_size.max(1))
    }

    /// Bytes a suspended CTA saves to memory and loads back when it resumes (paper sections
    /// 4.1 and 6.6): the raygen registers of every thread, and per warp `simt_stack_entries`
    /// entries of a SIMT mask, a PC and a reconvergence PC (all 32-bit). 2608 by default.
    pub fn cta_state_bytes(&self) -> u64 {
        let g = &self.gpu;
        let regs = g.threads_per_cta as u64 * g.raygen_regs_per_thread as u64 * WORD_BYTES;
        let stacks = self.warps_per_cta() as u64
            * g.simt_stack_entries as u64
            * WORDS_PER_SIMT_ENTRY
            * WORD_BYTES;
        regs + stacks
    }
}
