//! The treelet controller's registers: the mode and sequencer FSMs, the resident-treelet list,
//! per-slot bookkeeping, the fill sequence, the spare buffer and a pending count-table remove,
//! with their signals and descriptions declared once ([`table`]). Nothing else: its statistics
//! are counted by an observer from its output ports ([`super::ControllerStats::observe`]).

use serde::Serialize;

use super::{ControllerWidths, FillKind, Seq};
use crate::mode::Mode;
use crate::registers::RegTable;

/// One entry of the resident-treelet list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct ResidentEntry {
    /// The entry holds a treelet.
    pub valid: bool,
    /// Treelet address.
    pub treelet: u32,
    /// Rays waiting in its queue as the count table counts them: the table's maximum when it
    /// was claimed, plus later enqueues, minus pops; 0 once the table evicted it.
    pub count: u32,
    /// Its treelet warps still traversing.
    pub warps: u32,
}

/// What the controller knows about one warp-buffer slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct SlotState {
    /// The slot holds an initial-phase warp the controller terminated, still sending its rays
    /// to the queues (until its `warp_done`).
    pub terminated: bool,
    /// The slot holds a treelet warp the controller dispatched.
    pub treelet_warp: bool,
    /// The resident entry that warp belongs to (`None` for a naive untracked-queue warp).
    pub resident: Option<u32>,
}

/// The fill sequence in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct FillState {
    /// What is being built.
    pub kind: FillKind,
    /// Target warp-buffer slot.
    pub slot: u32,
    /// Resident entry popped from (treelet warps of a resident treelet).
    pub resident: Option<u32>,
    /// Lanes still to fill.
    pub need: u32,
    /// Rays were already given to the slot (or it is a repack, opened by the repack command).
    pub started: bool,
}

/// Every register of the controller.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ControllerRegs {
    /// Traversal mode FSM.
    pub mode: Mode,
    /// Queue-table sequencer FSM.
    pub seq: Seq,
    /// Rays in the queue table (exact: +1 per insert, -n per pop).
    pub queued_rays: u32,
    /// Resident-treelet list (`max_resident_treelets` entries), a circular buffer allocated at
    /// `res_tail`.
    pub res: Box<[ResidentEntry]>,
    /// Oldest valid resident entry (the current treelet).
    pub res_head: u32,
    /// Next entry to allocate.
    pub res_tail: u32,
    /// Per warp-buffer slot bookkeeping (`warp_buffer_size` entries).
    pub slots: Box<[SlotState]>,
    /// Fill sequence in progress (meaningful outside `Seq::Idle`).
    pub fill: FillState,
    /// Spare buffer: rays popped in the final phase that did not fit the warp being filled
    /// (fixed bank of warp_size - 1 ids; the first `spare_count` are valid).
    pub spare_rays: Box<[u32]>,
    /// Valid spare rays.
    pub spare_count: u32,
    /// A count-table `Remove` still to issue for a popped untracked entry: (treelet, rays).
    pub pending_remove: Option<(u32, u32)>,
}

impl ControllerRegs {
    /// Makes these registers equal to `other`, reusing their storage (same sizes: the same
    /// controller's registers).
    pub fn copy_from(&mut self, other: &ControllerRegs) {
        let ControllerRegs {
            mode,
            seq,
            queued_rays,
            res,
            res_head,
            res_tail,
            slots,
            fill,
            spare_rays,
            spare_count,
            pending_remove,
        } = other;
        self.mode = *mode;
        self.seq = *seq;
        self.queued_rays = *queued_rays;
        self.res.clone_from(res);
        self.res_head = *res_head;
        self.res_tail = *res_tail;
        self.slots.clone_from(slots);
        self.fill = *fill;
        self.spare_rays.clone_from(spare_rays);
        self.spare_count = *spare_count;
        self.pending_remove = *pending_remove;
    }

    /// Resident entry indices in age order (oldest first).
    pub(super) fn resident_order(&self) -> impl Iterator<Item = usize> + '_ {
        let n = self.res.len();
        (0..n)
            .map(move |k| (self.res_head as usize + k) % n)
            .filter(move |&i| self.res[i].valid)
    }

    /// Number of valid resident entries.
    pub(super) fn resident_count(&self) -> u32 {
        self.res.iter().filter(|e| e.valid).count() as u32
    }

    /// The resident entry holding `treelet`, if any.
    pub(super) fn resident_of(&self, treelet: u32) -> Option<usize> {
        self.res
            .iter()
            .position(|e| e.valid && e.treelet == treelet)
    }
}

/// The controller's registers for widths `w`: their descriptions and trace signals, declared
/// once.
pub(super) fn table(w: &ControllerWidths) -> RegTable<'static, ControllerRegs> {
    let b = |v: bool| v as u64;
    let (n, slots, spare) = (w.resident_entries, w.warp_slots, w.warp_size - 1);
    let mut t = RegTable::new();
    t.one(
        "mode",
        Mode::BITS,
        "Traversal mode FSM.",
        |r: &ControllerRegs| r.mode.encoding(),
    )
    .one("seq", Seq::BITS, "Queue-table sequencer FSM.", |r| {
        r.seq as u64
    })
    .one(
        "queued_rays",
        w.ray_total,
        "Rays in the queue table (exact).",
        |r| r.queued_rays as u64,
    )
    .bank(
        "res_valid",
        1,
        n,
        "Resident list: entry valid.",
        move |r, i| b(r.res[i].valid),
    )
    .bank(
        "res_treelet",
        w.treelet,
        n,
        "Resident list: treelet address.",
        |r, i| r.res[i].treelet as u64,
    )
    .bank(
        "res_count",
        w.ray_total,
        n,
        "Resident list: rays still queued for it.",
        |r, i| r.res[i].count as u64,
    )
    .bank(
        "res_warps",
        w.warps,
        n,
        "Resident list: its treelet warps in flight.",
        |r, i| r.res[i].warps as u64,
    )
    .one(
        "res_head",
        w.resident_index,
        "Oldest resident entry (current treelet).",
        |r| r.res_head as u64,
    )
    .one(
        "res_tail",
        w.resident_index,
        "Next resident entry to allocate.",
        |r| r.res_tail as u64,
    )
    .bank(
        "slot_terminated",
        1,
        slots,
        "Warp-buffer slot holds a terminated warp still sending its rays to the queues.",
        move |r, i| b(r.slots[i].terminated),
    )
    .bank(
        "slot_treelet_warp",
        1,
        slots,
        "Warp-buffer slot holds a dispatched treelet warp.",
        move |r, i| b(r.slots[i].treelet_warp),
    )
    .bank(
        "slot_res_valid",
        1,
        slots,
        "That warp belongs to a resident entry.",
        move |r, i| b(r.slots[i].resident.is_some()),
    )
    .bank(
        "slot_res",
        w.resident_index,
        slots,
        "Which resident entry.",
        |r, i| r.slots[i].resident.unwrap_or(0) as u64,
    )
    .one(
        "fill_kind",
        FillKind::BITS,
        "Fill sequence: what is being built.",
        |r| r.fill.kind as u64,
    )
    .one("fill_slot", w.slot, "Fill sequence: target slot.", |r| {
        r.fill.slot as u64
    })
    .one(
        "fill_res_valid",
        1,
        "Fill sequence: popping a resident treelet.",
        move |r| b(r.fill.resident.is_some()),
    )
    .one(
        "fill_res",
        w.resident_index,
        "Fill sequence: which resident entry.",
        |r| r.fill.resident.unwrap_or(0) as u64,
    )
    .one(
        "fill_need",
        w.lanes,
        "Fill sequence: lanes still to fill.",
        |r| r.fill.need as u64,
    )
    .one(
        "fill_started",
        1,
        "Fill sequence: the slot already received rays (or is a repack).",
        move |r| b(r.fill.started),
    )
    .one(
        "spare_count",
        w.lane,
        "Valid rays in the spare buffer.",
        |r| r.spare_count as u64,
    )
    .bank(
        "spare_rays",
        w.ray,
        spare,
        "Spare buffer: popped rays that did not fit the warp being filled.",
        |r, i| r.spare_rays[i] as u64,
    )
    .one(
        "prm_valid",
        1,
        "A count-table remove is pending.",
        move |r| b(r.pending_remove.is_some()),
    )
    .one("prm_treelet", w.treelet, "Its treelet.", |r| {
        r.pending_remove.map_or(0, |p| p.0) as u64
    })
    .one(
        "prm_count",
        w.ray_total,
        "Rays still to remove (a warp's worth per cycle).",
        |r| r.pending_remove.map_or(0, |p| p.1) as u64,
    );
    t
}
