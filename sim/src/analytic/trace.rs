//! The functional trace the analytical tier reads: every ray of the frame with the BVH nodes it
//! fetches (treelet order, as the simulated RT units traverse), grouped as the GPU issues them —
//! per SM (CTAs dealt round-robin, as the CTA scheduler does in steady state), per CTA, per
//! warp, per trip to the RT unit (the rays of one bounce level of the warp's live paths).

use rayon::prelude::*;

use crate::bvh::{HwBvh, NodeKind};
use crate::config::SimConfig;
use crate::gpu::cta_scheduler::CtaScheduler;
use crate::scene::Scene;
use crate::traversal::{trace_with_fetches, Fetch, Order};
use crate::workload::camera::CameraFrame;
use crate::workload::pathtracer::{PathState, RenderError};

/// One node fetch, compact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Node {
    /// Byte address.
    pub addr: u32,
    /// 32 B chunks (requests) it takes.
    pub chunks: u8,
    /// Intersection-test cycles after it returns.
    pub delay: u8,
    /// Its treelet.
    pub treelet: u32,
}

/// One trip of a warp to the RT unit: per lane that carries a ray, its fetches.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Trip {
    /// Per ray, its nodes in order.
    pub rays: Vec<Vec<Node>>,
}

/// The trips of one CTA: per warp, per bounce level.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct CtaTrips {
    /// `warps[w][level]`.
    pub warps: Vec<Vec<Trip>>,
}

/// The whole frame's trips, by CTA.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameTrace {
    /// Per CTA, in CTA order.
    pub ctas: Vec<CtaTrips>,
}

/// Intersection-test cycles of a node of `kind` (`cfg.rt.latencies`; a triangle leaf counts as
/// missed: the hit record's extra cycles are rare).
fn delay(cfg: &SimConfig, kind: NodeKind) -> u8 {
    let l = &cfg.rt.latencies;
    let cycles = match kind {
        NodeKind::Header => l.header,
        NodeKind::Internal => l.internal,
        NodeKind::TriangleLeaf => l.triangle_leaf,
        NodeKind::ProceduralLeaf => l.procedural,
    };
    cycles.min(u8::MAX as u32) as u8
}

impl FrameTrace {
    /// Traces `cfg`'s workload on `scene` (BVH `bvh`) on all rayon threads.
    pub fn new(scene: &Scene, bvh: &HwBvh, cfg: &SimConfig) -> Result<FrameTrace, RenderError> {
        let settings = cfg.render_settings();
        settings.validate()?;
        let frame = CameraFrame::new(&scene.camera, settings.width, settings.height)?;
        let scheduler = CtaScheduler::new(settings.width, settings.height, cfg.gpu.threads_per_cta);
        let warp_size = cfg.gpu.warp_size as usize;
        let node = |f: &Fetch| Node {
            addr: f.addr,
            chunks: f.bytes.div_ceil(32).clamp(1, u8::MAX as u32) as u8,
            delay: delay(cfg, f.kind),
            treelet: f.treelet,
        };
        let ctas = (0..scheduler.total())
            .into_par_iter()
            .map_init(Vec::new, |fetches, cta| {
                let pixels = scheduler.pixels(cta);
                let warps = pixels
                    .chunks(warp_size)
                    .map(|lanes| {
                        // Every sample of a lane's pixel is a path; trip k carries the k-th ray
                        // of every live path.
                        let mut paths: Vec<(PathState, crate::geometry::Ray)> = lanes
                            .iter()
                            .flatten()
                            .flat_map(|&p| (0..settings.spp).map(move |s| (p, s)))
                            .map(|(p, s)| PathState::new(&frame, &settings, p, s))
                            .collect();
                        let mut trips = Vec::new();
                        while !paths.is_empty() {
                            let mut trip = Trip::default();
                            let mut next = Vec::with_capacity(paths.len());
                            for (mut path, ray) in paths {
                                fetches.clear();
                                let hit = trace_with_fetches(bvh, &ray, Order::Hardware, fetches);
                                trip.rays.push(fetches.iter().map(node).collect());
                                if let Some(r) = path.on_hit(scene, hit) {
                                    next.push((path, r));
                                }
                            }
                            trips.push(trip);
                            paths = next;
                        }
                        trips
                    })
                    .collect();
                CtaTrips { warps }
            })
            .collect();
        Ok(FrameTrace { ctas })
    }

    /// The CTAs SM `sm` of `sms` runs (dealt round-robin), in order.
    pub fn sm_ctas(&self, sm: usize, sms: usize) -> impl Iterator<Item = &CtaTrips> {
        self.ctas.iter().skip(sm).step_by(sms.max(1))
    }

    /// The trips SM `sm` of `sms` issues, in issue order: its CTAs in groups of `group` (the
    /// CTAs in flight together), per group bounce level by bounce level, each level CTA by CTA
    /// and warp by warp. One entry per (group, level).
    pub fn sm_levels(&self, sm: usize, sms: usize, group: usize) -> Vec<Vec<&Trip>> {
        let ctas: Vec<&CtaTrips> = self.sm_ctas(sm, sms).collect();
        let mut out = Vec::new();
        for group in ctas.chunks(group.max(1)) {
            let levels = group
                .iter()
                .flat_map(|c| c.warps.iter().map(Vec::len))
                .max()
                .unwrap_or(0);
            for level in 0..levels {
                out.push(
                    group
                        .iter()
                        .flat_map(|c| c.warps.iter().filter_map(|w| w.get(level)))
                        .collect(),
                );
            }
        }
        out
    }
}
