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

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use toml::{Table, Value};
use vtq_hdl::controller::ControllerFeatures;
use vtq_hdl::rt_unit::{Latencies, RtUnitError, RtUnitParams};
use vtq_hdl::HwConfig;

use crate::model::bvh::WIDTH_RANGE;
use crate::model::bvh::{BvhParams, TreeletFormation};
use crate::model::memory::{MemConfig, MemConfigError};
use crate::model::workload::kind::WorkloadKind;
use crate::model::workload::pathtracer::RenderSettings;
use crate::model::workload::ray_file::RaySet;

mod energy;
mod mode;
mod overrides;
mod sample;
pub mod sample_points;
mod virtualization;

pub use energy::{CoefficientSet, EnergyConfig};
pub use mode::{ModeConfig, ModeKind, TreeletPrefetch};
pub use overrides::parse_override_value;
use overrides::{apply_override, merge, Origin};
pub use sample::{Cluster, SampleConfig};
pub use virtualization::{RestorePolicy, SuspendPolicy, VirtualizationConfig};

/// Workload keys that `--set` also accepts without their `workload.` prefix (`--set width=64`).
pub const BARE_KEYS: [&str; 4] = ["width", "height", "spp", "bounces"];

/// Bytes of one saved 32-bit value (register, SIMT mask, PC) of a suspended CTA.
const WORD_BYTES: u64 = 4;

/// Saved words per SIMT-stack entry of a suspended warp: active mask, PC, reconvergence PC.
const WORDS_PER_SIMT_ENTRY: u64 = 3;

/// A configuration could not be read, parsed, or holds an invalid value. Every variant names
/// the file, override or key concerned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// The configuration file could not be read.
    #[error("cannot read config file {}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },
    /// The configuration file is not valid TOML.
    #[error("config file {} is not valid TOML: {message}", path.display())]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line, column and an excerpt).
        message: String,
    },
    /// A `--set` argument is not of the form `key=value`.
    #[error("--set `{text}`: {reason}")]
    Override {
        /// The argument as given.
        text: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A key or section the configuration does not have.
    #[error("{origin}: unknown key `{key}`; {hint}")]
    UnknownKey {
        /// Where the key was given: the file or the `--set` argument.
        origin: String,
        /// The dotted key.
        key: String,
        /// The valid keys of its section (and a likely intended key, if any).
        hint: String,
    },
    /// A value of the wrong type for its key, or outside its type's range.
    #[error("{origin}: `{key}` = {value}: {reason}")]
    Type {
        /// Where the value was given: the file or the `--set` argument.
        origin: String,
        /// The dotted key.
        key: String,
        /// The value as TOML.
        value: String,
        /// The expected type.
        reason: String,
    },
    /// A value is out of range or inconsistent with another (found by [`SimConfig::validate`]).
    #[error("invalid configuration: {key} = {value}: {reason}")]
    Invalid {
        /// The dotted key.
        key: String,
        /// Its value.
        value: String,
        /// Why it is rejected.
        reason: String,
    },
    /// The configuration could not be converted to or from a TOML table (a value outside
    /// TOML's integer range, or a section missing from the merged table).
    #[error("configuration TOML conversion failed: {0}")]
    Toml(String),
}

impl ConfigError {
    /// The dotted key the error is about, when it is about one key.
    pub fn key(&self) -> Option<&str> {
        match self {
            ConfigError::UnknownKey { key, .. }
            | ConfigError::Type { key, .. }
            | ConfigError::Invalid { key, .. } => Some(key),
            ConfigError::Read { .. }
            | ConfigError::Syntax { .. }
            | ConfigError::Override { .. }
            | ConfigError::Toml(_) => None,
        }
    }
}

/// An [`ConfigError::Invalid`] for `key` = `value`.
fn invalid(key: &str, value: impl fmt::Display, reason: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        key: key.to_string(),
        value: value.to_string(),
        reason: reason.into(),
    }
}

/// Checks that `value` of `key` lies in `range`.
fn in_range<T>(key: &str, value: T, range: std::ops::RangeInclusive<T>) -> Result<(), ConfigError>
where
    T: PartialOrd + fmt::Display + Copy,
{
    if range.contains(&value) {
        Ok(())
    } else {
        Err(invalid(
            key,
            value,
            format!("must be {}..={}", range.start(), range.end()),
        ))
    }
}

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

/// `[gpu]`: the simulated GPU's SMs (paper Table 1) and the timing of the shaders run on them.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GpuConfig {
    /// Streaming multiprocessors (Table 1: 16).
    pub sms: u32,
    /// Resident warps per SM (Table 1: 32).
    pub max_warps_per_sm: u32,
    /// Threads per warp (Table 1: 32); must equal `hw.warp_size`.
    pub warp_size: u32,
    /// Resident CTAs per SM (Table 1: 16).
    pub max_ctas_per_sm: u32,
    /// Threads of one raygen CTA (64: an 8x8 pixel tile; modelling assumption).
    pub threads_per_cta: u32,
    /// 32-bit registers per SM (Table 1: 32768).
    pub registers_per_sm: u32,
    /// 32-bit registers per raygen thread (10, from ptxas, paper section 6.6); sets the
    /// registers a CTA occupies and the bytes a suspended CTA saves.
    pub raygen_regs_per_thread: u32,
    /// SIMT-stack entries saved per warp of a suspended CTA, each a 32-bit mask, a PC and a
    /// reconvergence PC (2: the bounce loop's reconvergence entry and the current one;
    /// modelling assumption).
    pub simt_stack_entries: u32,
    /// Cycles a warp spends in the raygen shader before each `traceRayEXT()` (camera-ray setup,
    /// or accumulation and scattering between bounces); modelling assumption.
    pub raygen_cycles: u32,
    /// Cycles of one closest-hit shader invocation of a warp (material evaluation); modelling
    /// assumption.
    pub closest_hit_cycles: u32,
    /// Cycles of one miss shader invocation of a warp (sky lookup); modelling assumption.
    pub miss_cycles: u32,
    /// Cycles from a free CTA slot to a new CTA's first instruction; modelling assumption.
    /// Saving and restoring a suspended CTA take no fixed time: they are
    /// [`SimConfig::cta_state_bytes`] of stores and loads through the memory system.
    pub cta_launch_cycles: u32,
}

impl Default for GpuConfig {
    fn default() -> Self {
        GpuConfig {
            sms: 16,
            max_warps_per_sm: 32,
            warp_size: 32,
            max_ctas_per_sm: 16,
            threads_per_cta: 64,
            registers_per_sm: 32768,
            raygen_regs_per_thread: 10,
            simt_stack_entries: 2,
            raygen_cycles: 100,
            closest_hit_cycles: 50,
            miss_cycles: 20,
            cta_launch_cycles: 20,
        }
    }
}

/// `[rt]`: RT-unit timing that is not a hardware size of [`HwConfig`]. The defaults are
/// [`RtUnitParams::default`]'s, so the simulator and the hardware models agree.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RtConfig {
    /// `[rt.latencies]`: intersection-test cycles per node kind (Vulkan-Sim's treelet-prefetching
    /// configuration: header 2,
    /// internal 4, instance_leaf 4, primitive_descriptor 2, triangle_leaf 4, triangle_hit 4,
    /// procedural 4).
    pub latencies: Latencies,
    /// Entries of the RT unit's response FIFO (8; modelling assumption of `vtq-hdl`).
    pub resp_fifo_depth: u32,
    /// Responses the memory system may deliver to the RT unit per cycle (2: an L1 hit return
    /// and a miss fill; modelling assumption of `vtq-hdl`).
    pub resp_ports: u32,
    /// Queues mode: whether a ray's traversal stacks move through memory while it waits in a
    /// treelet queue (false: they travel with its 32 B ray record for free, as the paper costs
    /// only the record). True: parking a ray stores the 32 B chunks holding its on-chip stack
    /// entries and forming a warp loads them back beside the record (class `ray_stack`).
    pub queued_stack_traffic: bool,
    /// Queues mode: where ray records are held. 0 (the default): in memory, a reserved part of
    /// the L2 (paper 4.2: ray data "resides in a reserved portion of the L2 cache"; loads and
    /// stores of 32 B bypass the L1). `N > 0`: on chip, in the register file or a dedicated
    /// partition "for quick access by the RT unit" (paper 3.1): a record load is answered `N`
    /// cycles after its request and neither loads nor stores reach the memory system. Written
    /// only when not 0, so configurations without it keep their text and result keys.
    #[serde(skip_serializing_if = "is_zero")]
    pub ray_record_latency: u32,
}

/// Whether `v` is 0 (a key left out of the configuration text at its default).
fn is_zero(v: &u32) -> bool {
    *v == 0
}

impl Default for RtConfig {
    fn default() -> Self {
        let p = RtUnitParams::default();
        RtConfig {
            latencies: p.latencies,
            resp_fifo_depth: p.resp_fifo_depth,
            resp_ports: p.resp_ports,
            queued_stack_traffic: false,
            ray_record_latency: 0,
        }
    }
}

/// The workload kinds `workload.kind` names.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum WorkloadKindName {
    /// The LumiBench path tracer (the paper's workload; closest-hit rays).
    #[default]
    Path,
    /// The path tracer with a shadow (occlusion) ray toward a sampled emitting triangle at
    /// each diffuse hit (`crate::model::workload::path_nee`).
    #[serde(rename = "path-nee")]
    PathNee,
    /// Ambient occlusion: a primary ray per sample, then `ao_rays` occlusion rays per
    /// primary hit (`crate::model::workload::ao`).
    Ao,
    /// Rays from the file `rays_file` (`crate::model::workload::ray_file`), one per pixel of a
    /// one-row image, in file order.
    Rays,
    /// The path tracer with its primary hits given, as rasterization gives them: only the
    /// secondary rays are traced (`crate::model::workload::kind::Sampler`).
    Hybrid,
}

impl WorkloadKindName {
    /// The name `workload.kind` takes.
    pub fn name(self) -> &'static str {
        match self {
            WorkloadKindName::Path => "path",
            WorkloadKindName::PathNee => "path-nee",
            WorkloadKindName::Ao => "ao",
            WorkloadKindName::Rays => "rays",
            WorkloadKindName::Hybrid => "hybrid",
        }
    }
}

/// `[workload]`: the traced image (the fields of [`RenderSettings`]; paper section 5.1) and
/// which rays its samples trace. Random numbers are seeded per pixel and sample (TEA), so the
/// workload has no seed key.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorkloadConfig {
    /// Image width in pixels (256).
    pub width: u32,
    /// Image height in pixels (256).
    pub height: u32,
    /// Samples (paths) per pixel (1).
    pub spp: u32,
    /// Maximum secondary rays per path (3); 0 traces primary rays only.
    pub bounces: u32,
    /// What each sample traces: `"path"` (the default), `"path-nee"`, `"ao"`, `"hybrid"` or
    /// `"rays"`.
    pub kind: WorkloadKindName,
    /// `ao`: occlusion rays per primary hit (4), 1..=64.
    pub ao_rays: u32,
    /// `ao`: the occlusion rays' length as a fraction of the scene's bounding-box diagonal
    /// (0.05), above 0 and at most 1.
    pub ao_radius: f64,
    /// `rays`: the ray file (CSV or binary, `crate::model::workload::ray_file`), relative to
    /// the working directory. Loading the configuration reads it and makes the image one row of
    /// one pixel per ray (`width` = the ray count, `height` = 1).
    pub rays_file: String,
    /// `rays`: the rays read from `rays_file` (not a key).
    #[serde(skip)]
    pub rays: Option<Arc<RaySet>>,
}

impl WorkloadConfig {
    /// With `kind = "rays"`, reads `rays_file` into `rays` and sizes the image to it (one row,
    /// one pixel per ray); otherwise drops any rays read before.
    pub fn read_rays(&mut self) -> Result<(), ConfigError> {
        if self.kind != WorkloadKindName::Rays {
            self.rays = None;
            return Ok(());
        }
        if self.rays_file.is_empty() {
            return Err(invalid(
                "workload.rays_file",
                "\"\"",
                "workload.kind = \"rays\" needs the ray file (CSV or binary) to trace",
            ));
        }
        let set = RaySet::read(&self.rays_file)
            .map_err(|e| invalid("workload.rays_file", &self.rays_file, e.to_string()))?;
        self.width = u32::try_from(set.rays.len()).unwrap_or(u32::MAX);
        self.height = 1;
        self.rays = Some(Arc::new(set));
        Ok(())
    }
}

impl Default for WorkloadConfig {
    fn default() -> Self {
        let r = RenderSettings::default();
        WorkloadConfig {
            width: r.width,
            height: r.height,
            spp: r.spp,
            bounces: r.bounces,
            kind: WorkloadKindName::Path,
            ao_rays: 4,
            ao_radius: 0.05,
            rays_file: String::new(),
            rays: None,
        }
    }
}

/// `[bvh]`: the hardware BVH build. Its treelet size is `hw.treelet_bytes`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BvhConfig {
    /// Children per internal node, 2..=8 (6, the public Vulkan-Sim build; the paper says 4).
    pub width: u32,
    /// How the BVH is partitioned into treelets: `packed` (the default: the breadth-first
    /// treelets packed into fuller slots, as the paper's section 6.5 does) or `breadth_first`
    /// (the treelet-prefetching code's greedy rule, one slot per treelet).
    pub treelet_formation: TreeletFormation,
}

impl Default for BvhConfig {
    fn default() -> Self {
        let p = BvhParams::default();
        BvhConfig {
            width: p.width,
            treelet_formation: p.formation,
        }
    }
}

/// `[sim]`: the simulation engine.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EngineConfig {
    /// Stop with a state dump after this many cycles without progress (100000). Must exceed
    /// one L1 + L2 + DRAM miss.
    pub watchdog_cycles: u64,
    /// Step every component every cycle instead of skipping idle cycles (verification mode;
    /// results must be identical).
    pub lockstep: bool,
    /// Cycles between time-series samples (1000); 0 records no time series.
    pub sample_interval: u64,
}

impl Default for EngineConfig {
    fn default() -> Self {
        EngineConfig {
            watchdog_cycles: 100_000,
            lockstep: false,
            sample_interval: 1000,
        }
    }
}

/// Largest cycle count accepted for the engine's cycle parameters (2^40).
const MAX_ENGINE_CYCLES: u64 = 1 << 40;

/// Largest cycle count accepted for one shader invocation or CTA launch.
const MAX_SHADER_CYCLES: u32 = 1_000_000;

/// Largest image side in pixels.
const MAX_IMAGE_SIDE: u32 = 16384;

/// Largest samples per pixel.
const MAX_SPP: u32 = 1024;

/// Largest bounces per path.
const MAX_BOUNCES: u32 = 64;

/// Most occlusion rays per primary hit (`workload.ao_rays`).
const MAX_AO_RAYS: u32 = 64;

/// Most rays of a ray file (`workload.rays_file`): the image's pixel count (one row).
const MAX_FILE_RAYS: u32 = 1 << 26;

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

    /// Checks every value's range and the rules between them, reporting the first violation
    /// with its dotted key, its value and the reason.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_gpu()?;
        self.validate_memory()?;
        self.validate_rt()?;
        self.validate_hw()?;
        self.validate_mode()?;
        self.validate_workload()?;
        self.validate_bvh()?;
        self.validate_engine()?;
        self.energy.validate()?;
        self.sample.validate_ranges()
    }

    /// Checks the sections the hardware is generated from: `[hw]` (every value's range),
    /// `[gpu]` (the CTA shape of the area model's suspended-CTA state, and the warp size shared
    /// with `[hw]`) and `[memory]` (a treelet fits the L1). Not checked: the rules that tie
    /// `[hw]` keys to `[mode]` (e.g. queue-table sizes differing from the defaults while
    /// mode.kind is not "queues"), which concern what the simulator runs.
    pub fn validate_hardware(&self) -> Result<(), ConfigError> {
        self.validate_hw_ranges()?;
        self.validate_gpu()?;
        self.validate_memory()
    }

    /// Checks every `[hw]` value's range ([`HwConfig::validate`]), naming the key as `hw.KEY`.
    fn validate_hw_ranges(&self) -> Result<(), ConfigError> {
        self.hw.validate().map_err(|e| ConfigError::Invalid {
            key: format!("hw.{}", e.key),
            value: e.value.to_string(),
            reason: e.reason,
        })
    }

    /// Checks the SMs, CTA slots, registers, shader timing and the warp size shared with `[hw]`.
    fn validate_gpu(&self) -> Result<(), ConfigError> {
        let g = &self.gpu;
        in_range("gpu.sms", g.sms, 1..=1024)?;
        in_range("gpu.max_warps_per_sm", g.max_warps_per_sm, 1..=128)?;
        if !g.warp_size.is_power_of_two() {
            return Err(invalid(
                "gpu.warp_size",
                g.warp_size,
                "must be a power of two",
            ));
        }
        in_range("gpu.warp_size", g.warp_size, 2..=64)?;
        if g.warp_size != self.hw.warp_size {
            return Err(invalid(
                "gpu.warp_size",
                g.warp_size,
                format!(
                    "differs from hw.warp_size ({}): the SM and the RT unit must use one warp \
                     size; set both",
                    self.hw.warp_size
                ),
            ));
        }
        in_range("gpu.max_ctas_per_sm", g.max_ctas_per_sm, 1..=128)?;
        in_range("gpu.threads_per_cta", g.threads_per_cta, 1..=1024)?;
        if !g.threads_per_cta.is_multiple_of(g.warp_size) {
            return Err(invalid(
                "gpu.threads_per_cta",
                g.threads_per_cta,
                format!(
                    "must be a multiple of gpu.warp_size ({}): CTAs are whole warps",
                    g.warp_size
                ),
            ));
        }
        let cta_threads = g.max_ctas_per_sm as u64 * g.threads_per_cta as u64;
        let warp_threads = g.max_warps_per_sm as u64 * g.warp_size as u64;
        if cta_threads > warp_threads {
            return Err(invalid(
                "gpu.max_ctas_per_sm",
                g.max_ctas_per_sm,
                format!(
                    "{} CTAs x {} threads = {cta_threads} threads exceed the SM's {} warps x {} \
                     = {warp_threads} threads",
                    g.max_ctas_per_sm, g.threads_per_cta, g.max_warps_per_sm, g.warp_size
                ),
            ));
        }
        in_range("gpu.registers_per_sm", g.registers_per_sm, 1..=1 << 20)?;
        in_range(
            "gpu.raygen_regs_per_thread",
            g.raygen_regs_per_thread,
            1..=255,
        )?;
        let regs = cta_threads * g.raygen_regs_per_thread as u64;
        if regs > g.registers_per_sm as u64 {
            return Err(invalid(
                "gpu.registers_per_sm",
                g.registers_per_sm,
                format!(
                    "too few for {} CTAs x {} threads x {} registers = {regs}",
                    g.max_ctas_per_sm, g.threads_per_cta, g.raygen_regs_per_thread
                ),
            ));
        }
        in_range("gpu.simt_stack_entries", g.simt_stack_entries, 1..=64)?;
        in_range("gpu.raygen_cycles", g.raygen_cycles, 1..=MAX_SHADER_CYCLES)?;
        in_range(
            "gpu.closest_hit_cycles",
            g.closest_hit_cycles,
            1..=MAX_SHADER_CYCLES,
        )?;
        in_range("gpu.miss_cycles", g.miss_cycles, 1..=MAX_SHADER_CYCLES)?;
        in_range(
            "gpu.cta_launch_cycles",
            g.cta_launch_cycles,
            0..=MAX_SHADER_CYCLES,
        )
    }

    /// Checks the memory system, and that a treelet fits the L1.
    fn validate_memory(&self) -> Result<(), ConfigError> {
        self.memory.validate().map_err(memory_error)?;
        let (treelet, l1) = (self.hw.treelet_bytes, self.memory.l1_bytes);
        if treelet as u64 > l1 as u64 {
            return Err(invalid(
                "hw.treelet_bytes",
                treelet,
                format!("a treelet must fit the L1 (memory.l1_bytes = {l1})"),
            ));
        }
        Ok(())
    }

    /// Checks intersection latencies and the response path.
    fn validate_rt(&self) -> Result<(), ConfigError> {
        let lat = &self.rt.latencies;
        match lat.validate() {
            Ok(()) => {}
            Err(RtUnitError::BadParam { value, reason, .. }) => {
                // The error carries the bad value; every latency equal to it is out of range,
                // so the first such key is a correct one to name.
                let table = Table::try_from(lat).map_err(|e| ConfigError::Toml(e.to_string()))?;
                let name = table
                    .iter()
                    .find(|(_, v)| v.as_integer() == Some(value as i64))
                    .map_or("latencies".to_string(), |(k, _)| k.clone());
                return Err(invalid(&format!("rt.latencies.{name}"), value, reason));
            }
            Err(other) => return Err(invalid("rt.latencies", "[rt.latencies]", other.to_string())),
        }
        in_range("rt.resp_fifo_depth", self.rt.resp_fifo_depth, 1..=1024)?;
        in_range("rt.resp_ports", self.rt.resp_ports, 1..=8)?;
        in_range(
            "rt.ray_record_latency",
            self.rt.ray_record_latency,
            0..=100_000,
        )
    }

    /// Checks the RT-unit hardware, and that its ray ids cover every ray the CTA slots issue.
    fn validate_hw(&self) -> Result<(), ConfigError> {
        self.validate_hw_ranges()?;
        let hw = &self.hw;
        let cta_rays = self.gpu.max_ctas_per_sm as u64 * self.gpu.threads_per_cta as u64;
        if (self.mode.virtualization || self.mode.treelet_queues())
            && (hw.max_rays as u64) < cta_rays
        {
            return Err(invalid(
                "hw.max_rays",
                hw.max_rays,
                format!(
                    "fewer than the rays the SM's CTA slots issue at once (gpu.max_ctas_per_sm x \
                     gpu.threads_per_cta = {cta_rays})"
                ),
            ));
        }
        Ok(())
    }

    /// Checks image size, samples, bounces and the workload kind's parameters.
    pub fn validate_workload(&self) -> Result<(), ConfigError> {
        let w = &self.workload;
        let widest = if w.kind == WorkloadKindName::Rays {
            MAX_FILE_RAYS
        } else {
            MAX_IMAGE_SIDE
        };
        in_range("workload.width", w.width, 1..=widest)?;
        in_range("workload.height", w.height, 1..=MAX_IMAGE_SIDE)?;
        in_range("workload.spp", w.spp, 1..=MAX_SPP)?;
        in_range("workload.bounces", w.bounces, 0..=MAX_BOUNCES)?;
        in_range("workload.ao_rays", w.ao_rays, 1..=MAX_AO_RAYS)?;
        if w.kind == WorkloadKindName::Hybrid && w.bounces == 0 {
            return Err(invalid(
                "workload.bounces",
                w.bounces,
                "with workload.kind = \"hybrid\" only secondary rays are traced: at least 1",
            ));
        }
        if w.kind == WorkloadKindName::Rays {
            let rays = w.rays.as_ref().map_or(0, |r| r.rays.len());
            if (w.width, w.height) != (rays as u32, 1) || rays == 0 {
                return Err(invalid(
                    "workload.width",
                    w.width,
                    format!(
                        "with workload.kind = \"rays\" the image is one row of one pixel per ray \
                         of workload.rays_file ({rays} rays): width {rays}, height 1"
                    ),
                ));
            }
            in_range("workload.spp", w.spp, 1..=1)?;
        }
        if !(w.ao_radius > 0.0 && w.ao_radius <= 1.0) {
            return Err(invalid(
                "workload.ao_radius",
                w.ao_radius,
                "must be above 0 and at most 1 (a fraction of the scene's bounding-box diagonal)",
            ));
        }
        Ok(())
    }

    /// Checks the BVH width, and the treelet size against it.
    fn validate_bvh(&self) -> Result<(), ConfigError> {
        let width = self.bvh.width;
        if !WIDTH_RANGE.contains(&width) {
            return Err(invalid(
                "bvh.width",
                width,
                format!("must be {}..={}", WIDTH_RANGE.start(), WIDTH_RANGE.end()),
            ));
        }
        if self.hw.stack_depth < width {
            return Err(invalid(
                "hw.stack_depth",
                self.hw.stack_depth,
                format!(
                    "must be at least bvh.width ({width}): a stack must hold one node's children"
                ),
            ));
        }
        // The width is valid, so what the build rejects is the treelet size for this width.
        self.bvh_params()
            .validate()
            .map_err(|e| invalid("hw.treelet_bytes", self.hw.treelet_bytes, e.to_string()))
    }

    /// Checks watchdog and time-series intervals.
    fn validate_engine(&self) -> Result<(), ConfigError> {
        let s = &self.sim;
        let m = &self.memory;
        let miss = m.l1_latency as u64 + m.l2_latency as u64 + m.dram_latency as u64;
        if s.watchdog_cycles <= miss || s.watchdog_cycles > MAX_ENGINE_CYCLES {
            return Err(invalid(
                "sim.watchdog_cycles",
                s.watchdog_cycles,
                format!(
                    "must exceed one L1 + L2 + DRAM miss ({miss} cycles) and be at most \
                     {MAX_ENGINE_CYCLES}"
                ),
            ));
        }
        in_range(
            "sim.sample_interval",
            s.sample_interval,
            0..=MAX_ENGINE_CYCLES,
        )
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

/// A [`MemConfig`] validation error as an [`ConfigError::Invalid`] naming its `memory.` key.
fn memory_error(e: MemConfigError) -> ConfigError {
    let (key, value) = match &e {
        MemConfigError::Zero { key } => (*key, 0),
        MemConfigError::NotPowerOfTwo { key, value }
        | MemConfigError::TooLarge { key, value, .. } => (*key, *value),
        MemConfigError::SectorVsLine { sector, .. } => ("sector_bytes", *sector),
        MemConfigError::SmallerThanLine { key, bytes, .. } => (*key, *bytes),
        MemConfigError::WaysDoNotDivide { key, ways, .. } => (*key, *ways),
        MemConfigError::RayWays { ray_ways, .. } => ("l2_ray_ways", *ray_ways),
        MemConfigError::NoSms => return invalid("gpu.sms", 0, e.to_string()),
        MemConfigError::DramShare { num, den } => {
            return invalid(
                "memory.dram_share",
                format!("[{num}, {den}]"),
                e.to_string(),
            )
        }
    };
    invalid(&format!("memory.{key}"), value, e.to_string())
}
