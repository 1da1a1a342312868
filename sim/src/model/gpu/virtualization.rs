//! Ray virtualization's memory traffic (paper sections 3.1, 4.1 and 6.6): each SM's
//! [`CtaStatePort`], which stores the state of suspending CTAs and loads it back for resuming
//! ones. (Which CTAs suspend and resume, and the ray budget, are the SM's: [`super::sm`].)
//!
//! A CTA's state (`SimConfig::cta_state_bytes`: the raygen registers of every thread and the
//! warps' SIMT stacks) has a fixed place per CTA number in a region after the hit records, as
//! the kernel management unit's table of terminated CTAs with their state address would give.
//! It moves as 32 B accesses of class [`AccessClass::CtaState`] (the last one shorter when the
//! size is not a multiple of 32 B) that bypass the L1 and go to the L2: the state is written
//! once and read once, so caching it in the L1 would only evict the BVH nodes (treelets) the RT
//! unit reuses there, as the paper avoids for ray data (section 5). The port holds the accesses
//! in one FIFO, separate from the RT unit's memory access queue, and offers at most one per
//! cycle through the SM's memory port; a refused access is retried from the cycle the memory
//! system names. FIFO order means a CTA's loads never overtake its stores.

use std::collections::{BTreeMap, VecDeque};

use vtq_hdl::rt_unit::CHUNK_BYTES;

use crate::model::gpu::error::SimError;
use crate::model::gpu::sm::CtaRef;
use crate::model::memory::{AccessClass, AccessError, L1Port, MemRequest, Response};

/// One queued CTA-state access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct StateAccess {
    /// The request; its tag is the CTA's virtual id on the SM.
    req: MemRequest,
    /// The last store of a CTA's state: once accepted, the CTA may leave its slot.
    last_store: bool,
}

/// What [`CtaStatePort::send`] did this cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateSend {
    /// Nothing was accepted (queue empty, or waiting after a stall).
    Idle,
    /// An access was accepted.
    Accepted,
    /// The last store of the CTA with this virtual id was accepted: its state is saved.
    Saved(usize),
}

/// One SM's CTA-state traffic.
#[derive(Debug, Clone)]
pub struct CtaStatePort {
    /// Address of CTA 0's state.
    base: u64,
    /// Bytes of one CTA's state.
    bytes: u64,
    /// Accesses not yet accepted by the L1, oldest first.
    queue: VecDeque<StateAccess>,
    /// First cycle the head of `queue` may be offered again after a stall.
    retry_at: u64,
    /// Loads not yet returned, per resuming CTA (virtual id).
    loads_left: BTreeMap<usize, u64>,
    /// Most accesses queued at once.
    max_queue: u64,
}

impl CtaStatePort {
    /// The port of an SM whose CTAs save `bytes` of state each, CTA `n`'s at
    /// `base + n x bytes` rounded up to 32 B.
    pub fn new(base: u64, bytes: u64) -> Self {
        CtaStatePort {
            base,
            bytes,
            queue: VecDeque::new(),
            retry_at: 0,
            loads_left: BTreeMap::new(),
            max_queue: 0,
        }
    }

    /// Accesses of one CTA's state.
    fn accesses(&self) -> u64 {
        self.bytes.div_ceil(CHUNK_BYTES as u64)
    }

    /// The `k`-th access of CTA `r`'s state as a load (bypassing the L1).
    fn load(&self, r: CtaRef, k: u64) -> MemRequest {
        let chunk = CHUNK_BYTES as u64;
        let stride = self.accesses() * chunk;
        let addr = self.base + r.cta as u64 * stride + k * chunk;
        let bytes = chunk.min(self.bytes - k * chunk) as u32;
        MemRequest::load(addr, bytes, AccessClass::CtaState, r.id as u64).bypassing_l1()
    }

    fn push(&mut self, access: StateAccess) {
        self.queue.push_back(access);
        self.max_queue = self.max_queue.max(self.queue.len() as u64);
    }

    /// Queues the stores of suspending CTA `r`'s state.
    pub fn save(&mut self, r: CtaRef) {
        let n = self.accesses();
        for k in 0..n {
            let l = self.load(r, k);
            self.push(StateAccess {
                req: MemRequest { store: true, ..l },
                last_store: k + 1 == n,
            });
        }
    }

    /// Queues the loads of resuming CTA `r`'s state.
    pub fn restore(&mut self, r: CtaRef) {
        let n = self.accesses();
        for k in 0..n {
            let req = self.load(r, k);
            self.push(StateAccess {
                req,
                last_store: false,
            });
        }
        self.loads_left.insert(r.id, n);
    }

    /// Offers the head of the queue to the SM's L1 in phase `phase` of cycle `now`.
    pub fn send(&mut self, now: u64, phase: u8, mem: &mut L1Port) -> Result<StateSend, SimError> {
        let Some(&head) = self.queue.front() else {
            return Ok(StateSend::Idle);
        };
        if now < self.retry_at {
            return Ok(StateSend::Idle);
        }
        match mem.access(now, phase, head.req) {
            Ok(_) => {
                self.queue.pop_front();
                Ok(if head.last_store {
                    StateSend::Saved(head.req.tag as usize)
                } else {
                    StateSend::Accepted
                })
            }
            Err(AccessError::Stall(s)) => {
                self.retry_at = s.retry_at.max(now + 1);
                Ok(StateSend::Idle)
            }
            Err(e) => Err(SimError::Memory(e)),
        }
    }

    /// Takes a CTA-state load response; returns the virtual id of the CTA whose last load it
    /// was (its state is restored).
    pub fn loaded(&mut self, r: &Response) -> Option<usize> {
        let id = r.tag as usize;
        let left = self.loads_left.get_mut(&id)?;
        *left -= 1;
        if *left > 0 {
            return None;
        }
        self.loads_left.remove(&id);
        Some(id)
    }

    /// The next cycle after `now` at which an access can be offered.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        (!self.queue.is_empty()).then(|| self.retry_at.max(now + 1))
    }

    /// A summary of the queue, for the watchdog.
    pub fn debug_state(&self) -> String {
        format!(
            "CTA-state port: {} accesses queued (most {}, retry at {}), loads outstanding per \
             resuming CTA id {:?}",
            self.queue.len(),
            self.max_queue,
            self.retry_at,
            self.loads_left
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::memory::{MemConfig, MemorySystem};

    #[test]
    fn a_cta_state_moves_as_32_byte_accesses_covering_its_bytes() {
        let port = CtaStatePort::new(1 << 20, 2608);
        assert_eq!(port.accesses(), 82);
        let r = CtaRef { id: 3, cta: 2 };
        let all: Vec<MemRequest> = (0..82).map(|k| port.load(r, k)).collect();
        assert_eq!(all.iter().map(|q| q.bytes as u64).sum::<u64>(), 2608);
        assert_eq!(all[0].addr, (1 << 20) + 2 * 82 * 32);
        assert_eq!(all[81].bytes, 16);
        assert!(all
            .iter()
            .all(|q| q.tag == 3 && q.class == AccessClass::CtaState && q.bypass_l1));
    }

    #[test]
    fn saves_report_the_last_store_and_restores_the_last_load() {
        let (mut ports, mut l2) = MemorySystem::new(&MemConfig::default(), 1)
            .unwrap()
            .into_parts();
        let mem = &mut ports[0];
        let mut port = CtaStatePort::new(0, 40);
        let r = CtaRef { id: 1, cta: 0 };
        port.save(r);
        port.restore(r);
        assert_eq!(port.next_event(5), Some(6));
        assert_eq!(port.send(0, 0, mem).unwrap(), StateSend::Accepted);
        assert_eq!(port.send(1, 0, mem).unwrap(), StateSend::Saved(1));
        assert_eq!(port.send(2, 0, mem).unwrap(), StateSend::Accepted);
        assert_eq!(port.send(3, 0, mem).unwrap(), StateSend::Accepted);
        assert_eq!(port.send(4, 0, mem).unwrap(), StateSend::Idle);
        assert_eq!(port.next_event(4), None);
        for k in 0..mem.ops().len() {
            let result = l2.apply(&mem.ops()[k]);
            mem.set_result(mem.first_op() + k as u64, result);
        }
        mem.settle();
        let loads: Vec<Response> = mem.pop_ready(u64::MAX >> 4).filter(|r| !r.store).collect();
        assert_eq!(loads.len(), 2);
        assert_eq!(port.loaded(&loads[0]), None);
        assert_eq!(port.loaded(&loads[1]), Some(1));
    }
}
