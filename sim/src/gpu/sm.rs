//! A streaming multiprocessor's thread side: CTA slots, warp slots, the warps' shader timers and
//! the queue of warps waiting to hand their rays to the SM's RT unit (`traceRayEXT()`).
//!
//! A warp cycles through: shader work (a timer) → waiting for the RT unit → in the RT unit →
//! shader work → ... until none of its threads traces again; the CTA retires when its last warp
//! ends, freeing the CTA slot and its warp slots.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};
use std::fmt::Write as _;

use crate::gpu::shader::PathThread;

/// Where a warp is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WarpState {
    /// Running shader code until the given cycle (then it traces, or ends if `last`).
    Shading {
        /// Cycle the shader work ends.
        until: u64,
        /// No thread traces again: the warp ends when the work is done.
        last: bool,
    },
    /// Waiting for the RT unit to accept it.
    WaitingRt,
    /// Its rays are in the RT unit.
    InRt,
}

/// A resident warp.
#[derive(Debug, Clone)]
pub struct Warp {
    /// CTA slot it belongs to.
    pub cta_slot: usize,
    /// Its threads (`None`: outside the image, or finished).
    pub threads: Vec<Option<PathThread>>,
    /// Where it is.
    pub state: WarpState,
}

/// A resident CTA.
#[derive(Debug, Clone, PartialEq, Eq)]
struct CtaSlot {
    /// CTA number.
    cta: u32,
    /// Warps not yet ended.
    live_warps: u32,
}

/// One SM.
#[derive(Debug, Clone)]
pub struct Sm {
    warps_per_cta: usize,
    ctas: Vec<Option<CtaSlot>>,
    warps: Vec<Option<Warp>>,
    /// Warps waiting for the RT unit, in the order they became ready.
    ready: VecDeque<usize>,
    /// Shader timers: (cycle, warp slot), earliest first, ties by warp slot.
    timers: BinaryHeap<Reverse<(u64, usize)>>,
    /// CTAs that ran to completion here.
    pub ctas_done: u64,
}

impl Sm {
    /// An idle SM with `cta_slots` CTA slots of `warps_per_cta` warps each.
    pub fn new(cta_slots: usize, warps_per_cta: usize) -> Self {
        Sm {
            warps_per_cta,
            ctas: vec![None; cta_slots],
            warps: vec![None; cta_slots * warps_per_cta],
            ready: VecDeque::new(),
            timers: BinaryHeap::new(),
            ctas_done: 0,
        }
    }

    /// Free CTA slots.
    pub fn free_slots(&self) -> u32 {
        self.ctas.iter().filter(|c| c.is_none()).count() as u32
    }

    /// Whether no CTA is resident.
    pub fn is_idle(&self) -> bool {
        self.ctas.iter().all(Option::is_none)
    }

    /// Launches CTA `cta` whose warps' threads are `warps`; its warps start tracing at `start`
    /// (after the launch and the first raygen work). Panics if no slot is free (the CTA scheduler
    /// only dispatches to free slots).
    pub fn launch(&mut self, cta: u32, warps: Vec<Vec<Option<PathThread>>>, start: u64) {
        let slot = self
            .ctas
            .iter()
            .position(Option::is_none)
            .expect("the CTA scheduler dispatches only to free slots");
        let mut live = 0;
        for (w, threads) in warps.into_iter().enumerate() {
            let idx = slot * self.warps_per_cta + w;
            let last = threads.iter().all(Option::is_none);
            live += 1;
            self.warps[idx] = Some(Warp {
                cta_slot: slot,
                threads,
                state: WarpState::Shading { until: start, last },
            });
            self.timers.push(Reverse((start, idx)));
        }
        self.ctas[slot] = Some(CtaSlot {
            cta,
            live_warps: live,
        });
    }

    /// Earliest shader timer.
    pub fn next_timer(&self) -> Option<u64> {
        self.timers.peek().map(|Reverse((c, _))| *c)
    }

    /// Ends the shader work due at or before `now`: warps that trace again join the RT queue,
    /// the others end (retiring their CTA when it was its last warp). Returns CTAs retired.
    pub fn run_timers(&mut self, now: u64) -> u32 {
        let mut retired = 0;
        while let Some(&Reverse((c, idx))) = self.timers.peek() {
            if c > now {
                break;
            }
            self.timers.pop();
            let Some(warp) = self.warps[idx].as_mut() else {
                continue;
            };
            match warp.state {
                WarpState::Shading { last: false, .. } => {
                    warp.state = WarpState::WaitingRt;
                    self.ready.push_back(idx);
                }
                WarpState::Shading { last: true, .. } => {
                    let slot = warp.cta_slot;
                    self.warps[idx] = None;
                    let cta = self.ctas[slot].as_mut().expect("a warp's CTA is resident");
                    cta.live_warps -= 1;
                    if cta.live_warps == 0 {
                        self.ctas[slot] = None;
                        self.ctas_done += 1;
                        retired += 1;
                    }
                }
                WarpState::WaitingRt | WarpState::InRt => {}
            }
        }
        retired
    }

    /// The warp at the head of the RT queue, if any.
    pub fn peek_ready(&self) -> Option<usize> {
        self.ready.front().copied()
    }

    /// Removes the head of the RT queue: the RT unit accepted it.
    pub fn issue_ready(&mut self) -> Option<usize> {
        let idx = self.ready.pop_front()?;
        if let Some(w) = self.warps[idx].as_mut() {
            w.state = WarpState::InRt;
        }
        Some(idx)
    }

    /// The warp in warp slot `idx`.
    pub fn warp(&self, idx: usize) -> Option<&Warp> {
        self.warps[idx].as_ref()
    }

    /// The warp in warp slot `idx`, mutably.
    pub fn warp_mut(&mut self, idx: usize) -> Option<&mut Warp> {
        self.warps[idx].as_mut()
    }

    /// Starts shader work of warp `idx` (its trace completed) ending at `until`; `last` when
    /// no thread traces again.
    pub fn start_shading(&mut self, idx: usize, until: u64, last: bool) {
        if let Some(w) = self.warps[idx].as_mut() {
            w.state = WarpState::Shading { until, last };
            self.timers.push(Reverse((until, idx)));
        }
    }

    /// A one-paragraph summary of the SM's state, for the watchdog.
    pub fn debug_state(&self) -> String {
        let mut out = String::new();
        let ctas: Vec<u32> = self.ctas.iter().flatten().map(|c| c.cta).collect();
        let _ = write!(
            out,
            "CTAs resident {ctas:?}, {} done; RT queue {:?}; next timer {:?}; warps:",
            self.ctas_done,
            self.ready,
            self.next_timer()
        );
        for (i, w) in self.warps.iter().enumerate() {
            if let Some(w) = w {
                let live = w.threads.iter().flatten().count();
                let _ = write!(out, " [{i}: {:?}, {live} threads]", w.state);
            }
        }
        out
    }
}
