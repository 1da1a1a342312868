//! Validation of a configuration ([`SimConfig::validate`]): every value's range and the rules
//! between sections, each violation reported with its dotted key, its value and the reason.

use toml::Table;
use vtq_hdl::rt_unit::RtUnitError;

use super::{in_range, invalid, memory_error, ConfigError, SimConfig, WorkloadKindName};
use crate::model::bvh::WIDTH_RANGE;

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
}
