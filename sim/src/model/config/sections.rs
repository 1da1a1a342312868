//! `[gpu]`, `[rt]`, `[bvh]` and `[sim]`: the GPU's SMs and shader timing, the RT-unit timing
//! not in `[hw]`, the hardware BVH build and the simulation engine.

use serde::{Deserialize, Serialize};
use vtq_hdl::rt_unit::{Latencies, RtUnitParams};

use crate::model::bvh::{BvhParams, TreeletFormation};

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
    /// [`SimConfig::cta_state_bytes`](super::SimConfig::cta_state_bytes) of stores and loads
    /// through the memory system.
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

/// `[rt]`: RT-unit timing that is not a hardware size of [`HwConfig`](vtq_hdl::HwConfig). The
/// defaults are [`RtUnitParams::default`]'s, so the simulator and the hardware models agree.
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
