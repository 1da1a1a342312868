//! The queue table's description (ports, registers, memories, FSM, timing) and its registers,
//! declared once with their trace signals.

use super::{QueueTable, QueueTableIn, QueueTableOut, QueueTableRegs};
use crate::block::Block;
use crate::describe::{block_params, BlockDesc, FsmDesc};
use crate::registers::RegTable;

impl QueueTable {
    /// The block's description for its configuration.
    pub(super) fn description(&self) -> BlockDesc {
        let w = self.widths;
        let c = &self.cfg;
        let regs = self.reset();
        let mut ports = QueueTableIn::ports(&w);
        ports.extend(QueueTableOut::ports(&w));
        let registers = self.registers().descs();
        let ray_fields: Vec<(String, u32)> = (0..w.lanes)
            .rev()
            .map(|i| (format!("ray_{i}"), w.ray))
            .collect();
        BlockDesc {
            name: "treelet_queue_table".into(),
            doc: "Treelet queue table (section 4.2, Figure 9): a hash table with chaining of \
                  entries holding a treelet address and up to one warp of ray ids; duplicate \
                  entries per treelet; overflow spills rays to memory."
                .into(),
            params: block_params!(c;
                queue_table_entries,
                buckets = self.buckets,
                warp_size, max_rays,
                treelet_addr_bits = w.treelet,
                ray_id_bits = w.ray,
            ),
            ports,
            registers,
            memories: vec![
                regs.heads.desc(
                    "heads",
                    vec![("valid".into(), 1), ("idx".into(), w.index)],
                    "Chain head per hash bucket (flip-flops).",
                ),
                regs.meta.desc(
                    "meta",
                    vec![
                        ("treelet".into(), w.treelet),
                        ("count_m1".into(), w.count_m1),
                        ("next_valid".into(), 1),
                        ("next".into(), w.index),
                    ],
                    "Entry metadata: treelet, fill count - 1, chain link (SRAM).",
                ),
                regs.rays.desc(
                    "rays",
                    ray_fields,
                    "Entry ray ids, one lane per warp slot, with a write enable per lane (SRAM).",
                ),
            ],
            fsms: vec![FsmDesc {
                name: "state".into(),
                states: ["IDLE", "WALK", "ANY_META", "POP_RAYS", "REFILL_WAIT"]
                    .map(String::from)
                    .to_vec(),
                width: 3,
            }],
            timing: vec![
                "One op at a time: accepted in IDLE (ready), done pulses with the results, ready \
                 again the next cycle. A chain walk reads one meta word per cycle (SRAM read \
                 latency 1). k = position of the treelet's first entry in its chain, L = chain \
                 length."
                    .into(),
                "Insert: 1 cycle (empty bucket), else 1 + k (1 + L if the treelet has no \
                 entry); spills in its last cycle when no entry is free."
                    .into(),
                "Pop: 2 + k cycles; not found: 1 (empty bucket) or 1 + L.".into(),
                "PopAny: 3 + k cycles (k in the popped entry's chain); empty table: 1.".into(),
                "Count: 1 (empty bucket) or 1 + L.".into(),
                "Refill: 1 if nothing is spilled; else 1 + wait for the answer, then the Insert \
                 cost starting in the answer cycle."
                    .into(),
                format!(
                    "Hash: XOR of the {}-bit treelet address in {}-bit groups from the LSB into {} buckets.",
                    w.treelet, w.bucket, self.buckets
                ),
            ],
        }
    }

    /// The registers (the scalar registers and the valid bits; the heads, metadata and rays
    /// are memories): their descriptions and trace signals, declared once.
    pub(super) fn registers(&self) -> RegTable<'static, QueueTableRegs> {
        let w = self.widths;
        let mut t = RegTable::new();
        t.one("state", 3, "FSM state", |r: &QueueTableRegs| {
            r.ctl.state as u64
        })
        .one(
            "walk_op",
            2,
            "op the walk serves: 0 Insert, 1 Pop, 2 Count, 3 PopAny",
            |r| r.ctl.walk_op as u64,
        )
        .one("key_treelet", w.treelet, "treelet of the current op", |r| {
            r.ctl.key_treelet
        })
        .one("key_ray", w.ray, "ray of the current Insert/Refill", |r| {
            r.ctl.key_ray as u64
        })
        .one("head_valid", 1, "bucket head at op start is valid", |r| {
            r.ctl.head.valid as u64
        })
        .one("head_idx", w.index, "bucket head at op start", |r| {
            r.ctl.head.idx as u64
        })
        .one(
            "cur",
            w.index,
            "entry whose meta word arrives this cycle",
            |r| r.ctl.cur as u64,
        )
        .one("prev_valid", 1, "an entry precedes cur", |r| {
            r.ctl.prev_valid as u64
        })
        .one("prev", w.index, "entry preceding cur", |r| {
            r.ctl.prev as u64
        })
        .one("prev_treelet", w.treelet, "its treelet", |r| {
            r.ctl.prev_treelet
        })
        .one("prev_count_m1", w.count_m1, "its count - 1", |r| {
            r.ctl.prev_count_m1 as u64
        })
        .one("target", w.index, "PopAny's entry", |r| r.ctl.target as u64)
        .one("acc", w.total, "Count's running sum", |r| r.ctl.acc as u64)
        .one("walked", w.entries, "entries read in this walk", |r| {
            r.ctl.walked as u64
        })
        .one(
            "pop_count_m1",
            w.count_m1,
            "popped entry's count - 1",
            |r| r.ctl.pop_count_m1 as u64,
        )
        .one("pop_treelet", w.treelet, "popped entry's treelet", |r| {
            r.ctl.pop_treelet
        })
        .one("free_count", w.entries, "free entries", |r| {
            r.ctl.free_count as u64
        })
        .one("spilled", w.spilled, "rays spilled and not refilled", |r| {
            r.ctl.spilled as u64
        })
        .bits(
            "valid",
            self.cfg.queue_table_entries,
            "entry valid bits (free list = complement)",
            |r, i| r.valid[i],
        );
        t
    }
}
