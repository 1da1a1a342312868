//! [`MemorySystem`]: per-SM L1 ports and the shared L2 and DRAM, with completion cycles fixed at
//! acceptance (the timing rules are in the [module documentation](super)).

use super::cache::SectorState;
use super::config::{MemConfig, MemConfigError};
use super::l1::{Acceptance, L1Port};
use super::l2::L2Side;
use super::request::{Accepted, AccessError, MemRequest, Response, Source};
use super::stats::MemStats;

/// The memory hierarchy of the simulated GPU: one L1 per SM, a shared L2 and its DRAM channels.
///
/// Every accepted access gets its completion cycle when it is accepted, so the memory system
/// has no per-cycle work: an engine calls [`access`](Self::access) in non-decreasing cycle
/// order, delivers responses with [`pop_ready`](Self::pop_ready), and may jump straight to
/// [`next_event`](Self::next_event) when nothing else happens in between. This is the plain
/// model: each access reaches the L2 as it is accepted. A simulator running SMs independently
/// between synchronisation points takes it apart ([`into_parts`](Self::into_parts)) and applies
/// the L1 ports' L2 operations itself, in the same order, with the same results.
#[derive(Debug, Clone)]
pub struct MemorySystem {
    cfg: MemConfig,
    ports: Vec<L1Port>,
    l2: L2Side,
}

impl MemorySystem {
    /// An empty memory system for `num_sms` SMs; fails on an invalid configuration or 0 SMs.
    pub fn new(cfg: &MemConfig, num_sms: usize) -> Result<Self, MemConfigError> {
        cfg.validate()?;
        if num_sms == 0 {
            return Err(MemConfigError::NoSms);
        }
        Ok(MemorySystem {
            cfg: cfg.clone(),
            ports: (0..num_sms).map(|sm| L1Port::new(cfg, sm as u32)).collect(),
            l2: L2Side::new(cfg),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MemConfig {
        &self.cfg
    }

    /// Number of SMs (L1s).
    pub fn num_sms(&self) -> usize {
        self.ports.len()
    }

    /// The SMs' L1 ports and the shared L2 side, for a simulator that applies L2 operations
    /// itself.
    pub fn into_parts(self) -> (Vec<L1Port>, L2Side) {
        (self.ports, self.l2)
    }

    /// Counters so far.
    pub fn stats(&self) -> MemStats {
        let mut stats = self.l2.stats();
        for port in &self.ports {
            stats.add(port.stats());
        }
        stats
    }

    /// Offers one request from SM `sm` at cycle `now` (cycles must not decrease from call to
    /// call). On success the access's completion cycle is fixed and, unless it is a
    /// prefetch, a [`Response`] is delivered at that cycle. `Err(AccessError::Stall)` means
    /// retry later (nothing changed but the stall counters); other errors are bad requests.
    pub fn access(
        &mut self,
        now: u64,
        sm: usize,
        req: MemRequest,
    ) -> Result<Accepted, AccessError> {
        let num_sms = self.ports.len();
        let port = self
            .ports
            .get_mut(sm)
            .ok_or(AccessError::NoSuchSm { sm, num_sms })?;
        match port.access(now, 0, req)? {
            Acceptance::Known(accepted) => Ok(accepted),
            Acceptance::Pending { op, merge } => {
                let first = port.first_op();
                for k in 0..port.ops().len() {
                    let id = first + k as u64;
                    if port.result(id).is_none() {
                        let result = self.l2.apply(&port.ops()[k]);
                        port.set_result(id, result);
                    }
                }
                let (done, source) = port.result(op).expect("applied above");
                port.settle();
                Ok(if merge {
                    Accepted {
                        done,
                        source: Source::L1Merge,
                    }
                } else {
                    Accepted { done, source }
                })
            }
        }
    }

    /// Removes and yields SM `sm`'s responses due at or before `now`, in completion-cycle
    /// order, ties in acceptance order (empty for an SM that does not exist). Responses the
    /// caller does not consume stay queued.
    pub fn pop_ready(&mut self, sm: usize, now: u64) -> impl Iterator<Item = Response> + '_ {
        self.ports
            .get_mut(sm)
            .into_iter()
            .flat_map(move |port| port.pop_ready(now))
    }

    /// Earliest cycle at which some SM has a response due, if any is queued. Fills without a
    /// response (prefetches) are not events: their effect is already in the cache state.
    pub fn next_event(&self) -> Option<u64> {
        self.ports.iter().filter_map(L1Port::next_response).min()
    }

    /// Completion cycle of SM `sm`'s next response, if one is queued (`None` also for an SM
    /// that does not exist). Only SM `sm`'s own accesses change it, so an engine can keep
    /// per-SM wake times.
    pub fn next_response(&self, sm: usize) -> Option<u64> {
        self.ports.get(sm).and_then(L1Port::next_response)
    }

    /// Responses queued for SM `sm` (0 for an SM that does not exist).
    pub fn pending_responses(&self, sm: usize) -> usize {
        self.ports.get(sm).map_or(0, L1Port::pending_responses)
    }

    /// State at cycle `now` of the L1 sector holding `addr` in SM `sm` (`None` when the SM
    /// does not exist).
    pub fn l1_sector(&self, sm: usize, addr: u64, now: u64) -> Option<SectorState> {
        self.ports.get(sm).map(|port| port.l1_sector(addr, now))
    }

    /// Whether SM `sm`'s L1 holds or is filling the sector of `addr` (false for an SM that
    /// does not exist). A prefetcher can skip such sectors.
    pub fn l1_contains(&self, sm: usize, addr: u64) -> bool {
        self.ports
            .get(sm)
            .is_some_and(|port| port.l1_contains(addr))
    }

    /// State at cycle `now` (in L2 time, i.e. the cycle a request reaches the L2) of the L2
    /// sector holding `addr`.
    pub fn l2_sector(&self, addr: u64, now: u64) -> SectorState {
        let line_shift = self.cfg.line_bytes.trailing_zeros();
        let line = addr >> line_shift;
        let sector = (addr & ((1 << line_shift) - 1)) >> self.cfg.sector_bytes.trailing_zeros();
        self.l2.sector(line, sector as u32, now)
    }

    /// A human-readable dump of the outstanding work at cycle `now`, for a deadlock watchdog.
    pub fn debug_state(&self, now: u64) -> String {
        let mut out = format!("memory at cycle {now}: {}\n", self.l2.debug_state(now));
        for port in &self.ports {
            out += "  ";
            out += &port.debug_state(now);
            out += "\n";
        }
        out
    }
}
