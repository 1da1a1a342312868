//! The memory side of the RT unit's environment: each cycle's responses, due ones in random
//! order as many as the response FIFO takes (rarely one more), and junk responses that match
//! no request.

use super::{Env, QUIET_CYCLES};
use vtq_hdl::rt_unit::{spill_area, MemResponse, RtUnitInputs, StatusSelect};
use vtq_hdl::{Cached, Moore};

impl Env {
    /// A response to no request: a copy of the last node chunk sent (a duplicate, which
    /// matches only a later load of that chunk by the same lane, whose own response then
    /// matches nothing or a later one), or under a random tag a hit-record address (never a
    /// node) with random data, or a spill-area address with no stack entries (never a fill).
    pub(super) fn junk(&mut self) -> MemResponse {
        if let Some(dup) = self.last_load.filter(|_| self.rng.chance(30)) {
            return dup;
        }
        let (base, end) = spill_area(self.block.config(), self.block.params());
        let tag = self.rng.below(1 << self.block.widths().tag) as u32;
        if self.rng.chance(50) {
            let records = self.block.params().hit_record_base;
            let address = records + 32 * self.rng.below(self.rays as u64);
            let data = std::array::from_fn(|_| self.rng.below(256) as u8);
            MemResponse { address, tag, data }
        } else {
            let address = base + 32 * self.rng.below((end - base) / 32);
            MemResponse {
                address,
                tag,
                data: [0; 32],
            }
        }
    }

    /// This cycle's responses: due ones in random order, as many as the FIFO takes (`resp_free`,
    /// or one more when the FIFO pops this cycle); rarely junk, or one more than the FIFO
    /// takes. Returns which are junk.
    pub(super) fn responses(&mut self, inp: &mut RtUnitInputs) -> Vec<bool> {
        let late = self.cycle >= QUIET_CYCLES;
        let cache = self.block.cache(&self.regs);
        let free = self
            .block
            .status(&self.regs, &cache, StatusSelect::Scalars)
            .resp_free as usize;
        let room = free + usize::from(!self.regs.fifo.is_empty());
        let ports = self.block.params().resp_ports as usize;
        self.overflow |= late && self.rng.below(400) == 0;
        let overflow = self.overflow && room < ports;
        self.overflow &= !overflow;
        let limit = match (overflow, room > free && self.rng.chance(50)) {
            (true, _) => room + 1,
            (false, more) => ports.min(if more { room } else { free }),
        };
        let mut junk = Vec::new();
        if late && limit > 0 && self.rng.below(500) == 0 {
            inp.responses.push(self.junk());
            junk.push(true);
        }
        let now = self.cycle;
        let mut due: Vec<usize> = (0..self.pending.len())
            .filter(|&i| self.pending[i].0 <= now)
            .collect();
        let mut chosen = Vec::new();
        while junk.len() + chosen.len() < limit && !due.is_empty() {
            let i = self.idx(due.len());
            chosen.push(due.swap_remove(i));
        }
        let spill = spill_area(self.block.config(), self.block.params());
        for &i in &chosen {
            let r = self.pending[i].1;
            if !(spill.0..spill.1).contains(&r.address) {
                self.last_load = Some(r);
            }
            inp.responses.push(r);
            junk.push(false);
        }
        chosen.sort_unstable();
        for &i in chosen.iter().rev() {
            self.pending.swap_remove(i);
        }
        while overflow && junk.len() < limit {
            inp.responses.push(self.junk());
            junk.push(true);
        }
        junk
    }
}
