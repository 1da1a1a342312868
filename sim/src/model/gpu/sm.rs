//! A streaming multiprocessor's thread side: CTA slots, the CTAs and warps it holds, the warps'
//! shader timers and the queue of warps waiting to hand their rays to the SM's RT unit
//! (`traceRayEXT()`).
//!
//! A warp cycles through: shader work (a timer) → waiting for the RT unit → in the RT unit →
//! shader work → ... until none of its threads traces again; the CTA retires when its last warp
//! ends, freeing its CTA slot and warp slots.
//!
//! CTAs and warps are named by virtual ids that stay valid while a CTA is out of its slot, so
//! the RT unit can hold a warp handle across a suspension: CTA `id` owns warps
//! `id * warps_per_cta ..` of the warp table. Without ray virtualization every CTA holds a slot,
//! ids are the lowest free ones and equal the physical slot numbers. With ray virtualization
//! ([`Sm::with_virtualization`], paper section 3.1) a CTA whose live warps all wait for or are
//! in the RT unit is suspended: its state is stored (it keeps its slot until the last store is
//! accepted), then it leaves its slot; when all its rays have completed traversal it is ready
//! to resume, takes a free slot before any new CTA, loads its state back, and only then shades
//! the hits its warps received meanwhile. The table grows as CTAs are suspended; its size is
//! bounded by the ray budget, since every CTA reserves its live threads.
//!
//! The `[virtualization]` switches change when this happens ([`VirtualizationConfig`]): a CTA
//! may be suspended only when its slot is wanted (`on_demand`), load its state as soon as it is
//! ready rather than when it gets a slot (`on_ready`), or move no state at all
//! (`state_traffic = false`, an idealisation).

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};
use std::fmt::Write as _;

use crate::model::config::{RestorePolicy, SuspendPolicy, VirtualizationConfig};
use crate::model::gpu::rt::TracedWarp;
use crate::model::gpu::shader::PathThread;
use crate::model::gpu::stats::VirtTiming;

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
    /// Its traversal completed while its CTA was suspended: the hits wait with the warp until
    /// the CTA has resumed.
    Traced,
}

/// A warp of a CTA on the SM (resident or suspended).
#[derive(Debug, Clone)]
pub struct Warp {
    /// Virtual id of its CTA.
    pub cta_id: usize,
    /// Its threads (`None`: outside the image, or finished).
    pub threads: Vec<Option<PathThread>>,
    /// Where it is.
    pub state: WarpState,
    /// The completed traversal kept while the CTA is suspended ([`WarpState::Traced`]).
    traced: Option<TracedWarp>,
}

/// Where a CTA is with respect to ray virtualization.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum CtaPhase {
    /// In a CTA slot, executing.
    Running,
    /// Every live warp traces: its state is being stored; it still holds its slot.
    Suspending,
    /// Its state is in memory and its slot is free.
    Suspended,
    /// Back in a slot, its state being loaded.
    Resuming,
}

/// A CTA on the SM.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Cta {
    /// CTA number.
    cta: u32,
    /// Where it is.
    phase: CtaPhase,
    /// Warps not yet ended.
    live_warps: u32,
    /// Warps waiting for or in the RT unit.
    tracing_warps: u32,
    /// Threads not finished: the rays this CTA may still have in flight.
    live_threads: u64,
    /// Its saved state is back (or was never moved): it may run once it holds a slot.
    state_loaded: bool,
    /// Cycle it started suspending.
    suspended_at: u64,
    /// Cycle it became ready to resume.
    ready_at: u64,
    /// Cycle it got a slot to resume in.
    slot_at: u64,
    /// Cycle its warps first started tracing (after launch and raygen).
    started_at: u64,
}

/// When a CTA ran on its SM: from its warps' first trace (after launch and raygen) to its
/// retirement (`vtq sim --ctas`; docs/accuracy.md uses it to locate the sampled tier's error).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CtaSpan {
    /// CTA number (pixel tile).
    pub cta: u32,
    /// Cycle its warps started tracing.
    pub start: u64,
    /// Cycle it retired.
    pub end: u64,
}

/// A CTA named by its virtual id on the SM and its CTA number (which places its saved state).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CtaRef {
    /// Virtual id on the SM (its warps are `id * warps_per_cta ..`).
    pub id: usize,
    /// CTA number (pixel tile).
    pub cta: u32,
}

/// Ray virtualization on one SM: the ray budget and the `[virtualization]` switches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RayBudget {
    /// Rays in flight per SM at most (`hw.max_rays`).
    pub max_rays: u64,
    /// Threads of one CTA: what a new CTA needs from the budget.
    pub cta_threads: u64,
    /// When CTAs suspend and restore, and whether their state moves through memory.
    pub policy: VirtualizationConfig,
}

/// What [`Sm::resume`] did with a CTA it put into a slot.
#[derive(Debug, Clone, PartialEq)]
pub enum Resumed {
    /// Its state must be loaded now (`restore = "on_slot"`).
    Load(CtaRef),
    /// Its state is being loaded already (`restore = "on_ready"`).
    Loading(CtaRef),
    /// Its state is back: it runs now; shade its warps' traversals (in warp order).
    Run(Vec<TracedWarp>),
}

/// One SM.
#[derive(Debug, Clone)]
pub struct Sm {
    warps_per_cta: usize,
    /// CTA slots.
    slots: usize,
    /// CTAs holding a slot (running, suspending or resuming).
    resident: usize,
    /// Ray virtualization's budget (`None`: no virtualization).
    budget: Option<RayBudget>,
    /// CTAs by virtual id.
    ctas: Vec<Option<Cta>>,
    /// Warps by virtual id.
    warps: Vec<Option<Warp>>,
    /// Warps waiting for the RT unit, in the order they became ready.
    ready: VecDeque<usize>,
    /// Shader timers: (cycle, warp id), earliest first, ties by warp id.
    timers: BinaryHeap<Reverse<(u64, usize)>>,
    /// Suspended CTAs whose rays have all completed, in the order they became ready.
    resumable: VecDeque<usize>,
    /// CTAs that became ready to resume whose state is to be loaded at once
    /// (`restore = "on_ready"`), in that order.
    to_load: Vec<CtaRef>,
    /// CTAs suspending (still holding their slots).
    suspending: usize,
    /// Live threads of all CTAs on the SM (each may still trace a ray).
    reserved: u64,
    /// Rays issued or waiting to issue whose traversal has not completed.
    in_flight: u64,
    /// Most rays in flight at once.
    pub max_in_flight: u64,
    /// CTAs that ran to completion here, in the order they retired.
    pub done: Vec<CtaSpan>,
    /// CTAs suspended.
    pub suspends: u64,
    /// CTAs resumed.
    pub resumes: u64,
    /// Where suspended CTAs' time went.
    pub timing: VirtTiming,
}

impl Sm {
    /// An idle SM with `cta_slots` CTA slots of `warps_per_cta` warps each.
    pub fn new(cta_slots: usize, warps_per_cta: usize) -> Self {
        Sm {
            warps_per_cta,
            slots: cta_slots,
            resident: 0,
            budget: None,
            ctas: vec![None; cta_slots],
            warps: vec![None; cta_slots * warps_per_cta],
            ready: VecDeque::new(),
            timers: BinaryHeap::new(),
            resumable: VecDeque::new(),
            to_load: Vec::new(),
            suspending: 0,
            reserved: 0,
            in_flight: 0,
            max_in_flight: 0,
            done: Vec::new(),
            suspends: 0,
            resumes: 0,
            timing: VirtTiming::default(),
        }
    }

    /// The same SM with ray virtualization: at most `budget.max_rays` rays in flight, a new CTA
    /// (of `budget.cta_threads` threads) launched only if its threads fit.
    pub fn with_virtualization(self, budget: RayBudget) -> Self {
        Sm {
            budget: Some(budget),
            ..self
        }
    }

    /// The switches of ray virtualization, if it is on.
    fn policy(&self) -> Option<VirtualizationConfig> {
        self.budget.map(|b| b.policy)
    }

    /// New CTAs the ray budget admits besides the live threads of the CTAs the SM holds
    /// (unlimited without virtualization).
    fn budget_fit(&self) -> u64 {
        match self.budget {
            None => u64::MAX,
            Some(b) => b.max_rays.saturating_sub(self.reserved) / b.cta_threads.max(1),
        }
    }

    /// Free CTA slots.
    pub fn free_slots(&self) -> u32 {
        (self.slots - self.resident) as u32
    }

    /// New CTAs the SM can take now: its free slots, and with ray virtualization only as many
    /// as fit the ray budget besides the live threads of the CTAs it already holds.
    pub fn launchable(&self) -> u32 {
        let free = self.free_slots();
        free.min(self.budget_fit().min(u32::MAX as u64) as u32)
    }

    /// Whether the CTA dispatch has something to do on this SM: a CTA ready to resume and a
    /// free slot, (when CTAs are `pending`) room for a new CTA, or (`suspend = "on_demand"`) a
    /// CTA to suspend for a slot that is wanted.
    pub fn can_dispatch(&self, pending: bool) -> bool {
        let free = self.free_slots() > 0;
        (free && !self.resumable.is_empty())
            || (pending && self.launchable() > 0)
            || self.suspend_wanted(pending)
    }

    /// `suspend = "on_demand"`: how many more slots are wanted than are free or being freed by
    /// suspending CTAs — one per CTA still `pending` at the CTA scheduler that fits the ray
    /// budget, and one per suspended CTA of this SM ready to resume (0 with another policy).
    fn slots_wanted(&self, pending: bool) -> usize {
        if self.policy().map(|p| p.suspend) != Some(SuspendPolicy::OnDemand) {
            return 0;
        }
        let new = if pending {
            self.budget_fit().min(self.slots as u64) as usize
        } else {
            0
        };
        let have = self.slots - self.resident + self.suspending;
        (new + self.resumable.len()).saturating_sub(have)
    }

    /// Running CTAs whose live warps all wait for or are in the RT unit, by virtual id.
    fn suspendable(&self) -> impl Iterator<Item = usize> + '_ {
        self.ctas.iter().enumerate().filter_map(|(id, c)| {
            let c = c.as_ref()?;
            (c.phase == CtaPhase::Running && c.tracing_warps == c.live_warps).then_some(id)
        })
    }

    /// `suspend = "on_demand"`: whether a CTA should be suspended now (with CTAs `pending` at the
    /// CTA scheduler or not) to free a wanted slot.
    pub fn suspend_wanted(&self, pending: bool) -> bool {
        self.slots_wanted(pending) > 0 && self.suspendable().next().is_some()
    }

    /// `suspend = "on_demand"`: suspends, at cycle `now`, as many suspendable CTAs (lowest
    /// virtual id first) as slots are wanted ([`Sm::suspend_wanted`]); returns them: their state
    /// is to be stored. `pending` must be exact (after the CTA dispatch of `now`).
    pub fn suspend_on_demand(&mut self, pending: bool, now: u64) -> Vec<CtaRef> {
        let wanted = self.slots_wanted(pending);
        if wanted == 0 {
            return Vec::new();
        }
        let ids: Vec<usize> = self.suspendable().take(wanted).collect();
        ids.into_iter()
            .map(|id| self.start_suspend(id, now))
            .collect()
    }

    /// Whether no CTA is on the SM (resident or suspended).
    pub fn is_idle(&self) -> bool {
        self.ctas.iter().all(Option::is_none)
    }

    /// Launches CTA `cta` whose warps' threads are `warps`; its warps start tracing at `start`
    /// (after the launch and the first raygen work). Panics if no slot is free (the CTA scheduler
    /// only dispatches to free slots).
    pub fn launch(&mut self, cta: u32, warps: Vec<Vec<Option<PathThread>>>, start: u64) {
        assert!(
            self.resident < self.slots,
            "the CTA scheduler dispatches only to free slots"
        );
        let id = match self.ctas.iter().position(Option::is_none) {
            Some(id) => id,
            None => {
                self.ctas.push(None);
                self.warps
                    .extend(std::iter::repeat_n(None, self.warps_per_cta));
                self.ctas.len() - 1
            }
        };
        let mut live = 0;
        let mut threads_live = 0;
        for (w, threads) in warps.into_iter().enumerate() {
            let idx = id * self.warps_per_cta + w;
            let n = threads.iter().flatten().count() as u64;
            live += 1;
            threads_live += n;
            self.warps[idx] = Some(Warp {
                cta_id: id,
                threads,
                state: WarpState::Shading {
                    until: start,
                    last: n == 0,
                },
                traced: None,
            });
            self.timers.push(Reverse((start, idx)));
        }
        self.ctas[id] = Some(Cta {
            cta,
            phase: CtaPhase::Running,
            live_warps: live,
            tracing_warps: 0,
            live_threads: threads_live,
            state_loaded: true,
            suspended_at: 0,
            ready_at: 0,
            slot_at: 0,
            started_at: start,
        });
        self.resident += 1;
        self.reserved += threads_live;
    }

    /// Earliest shader timer.
    pub fn next_timer(&self) -> Option<u64> {
        self.timers.peek().map(|Reverse((c, _))| *c)
    }

    /// Ends the shader work due at or before `now`: warps that trace again join the RT queue,
    /// the others end (retiring their CTA when it was its last warp). Returns the CTAs that
    /// start suspending (ray virtualization), whose state is to be stored.
    pub fn run_timers(&mut self, now: u64) -> Vec<CtaRef> {
        let mut suspended = Vec::new();
        while let Some(&Reverse((c, idx))) = self.timers.peek() {
            if c > now {
                break;
            }
            self.timers.pop();
            let Some(warp) = self.warps[idx].as_mut() else {
                continue;
            };
            let id = warp.cta_id;
            match warp.state {
                WarpState::Shading { last: false, .. } => {
                    warp.state = WarpState::WaitingRt;
                    self.in_flight += warp.threads.iter().flatten().count() as u64;
                    self.max_in_flight = self.max_in_flight.max(self.in_flight);
                    self.ready.push_back(idx);
                    self.cta_mut(id).tracing_warps += 1;
                }
                WarpState::Shading { last: true, .. } => {
                    self.warps[idx] = None;
                    let cta = self.cta_mut(id);
                    cta.live_warps -= 1;
                    if cta.live_warps == 0 {
                        let (left, span) = (
                            cta.live_threads,
                            CtaSpan {
                                cta: cta.cta,
                                start: cta.started_at,
                                end: now,
                            },
                        );
                        self.ctas[id] = None;
                        self.resident -= 1;
                        self.reserved -= left;
                        self.done.push(span);
                        continue;
                    }
                }
                WarpState::WaitingRt | WarpState::InRt | WarpState::Traced => continue,
            }
            if let Some(s) = self.try_suspend(id, now) {
                suspended.push(s);
            }
        }
        suspended
    }

    /// Suspends CTA `id` at cycle `now` if ray virtualization is on with `suspend = "eager"`,
    /// the CTA runs, and every live warp traces.
    fn try_suspend(&mut self, id: usize, now: u64) -> Option<CtaRef> {
        if self.policy()?.suspend != SuspendPolicy::Eager {
            return None;
        }
        let cta = self.cta_mut(id);
        if cta.phase != CtaPhase::Running || cta.tracing_warps != cta.live_warps {
            return None;
        }
        Some(self.start_suspend(id, now))
    }

    /// CTA `id` (running, every live warp tracing) starts suspending at cycle `now`.
    fn start_suspend(&mut self, id: usize, now: u64) -> CtaRef {
        let traffic = self.policy().is_none_or(|p| p.state_traffic);
        let cta = self.cta_mut(id);
        cta.phase = CtaPhase::Suspending;
        cta.suspended_at = now;
        cta.state_loaded = !traffic;
        let r = CtaRef { id, cta: cta.cta };
        self.suspends += 1;
        self.suspending += 1;
        r
    }

    /// Suspended CTA `id` became ready to resume at cycle `now` (all its rays traced, its state
    /// saved).
    fn became_ready(&mut self, id: usize, now: u64) {
        let policy = self.policy();
        let cta = self.cta_mut(id);
        cta.ready_at = now;
        let r = CtaRef { id, cta: cta.cta };
        let load_now =
            !cta.state_loaded && policy.is_some_and(|p| p.restore == RestorePolicy::OnReady);
        self.resumable.push_back(id);
        if load_now {
            self.to_load.push(r);
        }
    }

    /// `restore = "on_ready"`: the CTAs that became ready to resume since the last call, whose
    /// state is to be loaded now, in that order.
    pub fn take_to_load(&mut self) -> Vec<CtaRef> {
        std::mem::take(&mut self.to_load)
    }

    /// The CTA with virtual id `id` (it exists: warps name only CTAs on the SM).
    fn cta_mut(&mut self, id: usize) -> &mut Cta {
        self.ctas[id].as_mut().expect("a warp's CTA is on the SM")
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

    /// The warp with id `idx`.
    pub fn warp(&self, idx: usize) -> Option<&Warp> {
        self.warps.get(idx)?.as_ref()
    }

    /// The warp with id `idx`, mutably.
    pub fn warp_mut(&mut self, idx: usize) -> Option<&mut Warp> {
        self.warps.get_mut(idx)?.as_mut()
    }

    /// The RT unit completed warp `done.warp`'s traversal at cycle `now`. Returns it when its
    /// CTA runs (shade it now); while the CTA is suspended the hits stay with the warp until it
    /// has resumed, and the CTA becomes ready to resume once all its traversals have completed.
    pub fn traversal_done(&mut self, done: TracedWarp, now: u64) -> Option<TracedWarp> {
        let id = self.warps.get(done.warp)?.as_ref()?.cta_id;
        self.in_flight -= done.hits.iter().flatten().count() as u64;
        let cta = self.cta_mut(id);
        cta.tracing_warps -= 1;
        let (phase, tracing) = (cta.phase, cta.tracing_warps);
        if phase == CtaPhase::Running {
            return Some(done);
        }
        if phase == CtaPhase::Suspended && tracing == 0 {
            self.became_ready(id, now);
        }
        if let Some(w) = self.warps[done.warp].as_mut() {
            w.state = WarpState::Traced;
            w.traced = Some(done);
        }
        None
    }

    /// Starts shader work of warp `idx` (its trace completed and was shaded, `finished` of its
    /// threads ended) ending at `until`; `last` when no thread traces again.
    pub fn start_shading(&mut self, idx: usize, until: u64, last: bool, finished: u64) {
        let Some(w) = self.warps[idx].as_mut() else {
            return;
        };
        w.state = WarpState::Shading { until, last };
        let id = w.cta_id;
        self.timers.push(Reverse((until, idx)));
        self.cta_mut(id).live_threads -= finished;
        self.reserved -= finished;
    }

    /// At cycle `now` the last store of suspending CTA `id`'s state was accepted (or, without
    /// state traffic, it started suspending): it leaves its slot, and is ready to resume at
    /// once if its rays have all completed meanwhile.
    pub fn state_saved(&mut self, id: usize, now: u64) {
        let cta = self.cta_mut(id);
        cta.phase = CtaPhase::Suspended;
        let ready = cta.tracing_warps == 0;
        let saved = now - cta.suspended_at;
        self.timing.save_cycles += saved;
        self.resident -= 1;
        self.suspending -= 1;
        if ready {
            self.became_ready(id, now);
        }
    }

    /// Puts CTAs ready to resume into free slots at cycle `now`, in the order they became ready
    /// (before any new CTA is launched); returns what is to be done with each.
    pub fn resume(&mut self, now: u64) -> Vec<Resumed> {
        let mut out = Vec::new();
        let on_ready = self
            .policy()
            .is_some_and(|p| p.restore == RestorePolicy::OnReady);
        while self.resident < self.slots {
            let Some(id) = self.resumable.pop_front() else {
                break;
            };
            let cta = self.cta_mut(id);
            cta.phase = CtaPhase::Resuming;
            cta.slot_at = now;
            let (r, loaded, waited) = (
                CtaRef { id, cta: cta.cta },
                cta.state_loaded,
                now - cta.ready_at,
            );
            self.timing.resume_wait_cycles += waited;
            self.resident += 1;
            self.resumes += 1;
            out.push(if loaded {
                Resumed::Run(self.run_again(id))
            } else if on_ready {
                Resumed::Loading(r)
            } else {
                Resumed::Load(r)
            });
        }
        out
    }

    /// At cycle `now` the last load of suspended CTA `id`'s state returned. A CTA holding a slot
    /// runs again: returns its warps' completed traversals, in warp order, to be shaded now. A
    /// CTA still waiting for a slot (`restore = "on_ready"`) runs as soon as it gets one.
    pub fn state_restored(&mut self, id: usize, now: u64) -> Vec<TracedWarp> {
        let cta = self.cta_mut(id);
        cta.state_loaded = true;
        if cta.phase != CtaPhase::Resuming {
            return Vec::new();
        }
        let restore = now - cta.slot_at;
        self.timing.restore_cycles += restore;
        self.run_again(id)
    }

    /// Resuming CTA `id` runs again: returns its warps' completed traversals, in warp order.
    fn run_again(&mut self, id: usize) -> Vec<TracedWarp> {
        self.cta_mut(id).phase = CtaPhase::Running;
        let range = id * self.warps_per_cta..(id + 1) * self.warps_per_cta;
        self.warps[range]
            .iter_mut()
            .flatten()
            .filter_map(|w| w.traced.take())
            .collect()
    }

    /// A one-paragraph summary of the SM's state, for the watchdog.
    pub fn debug_state(&self) -> String {
        let mut out = String::new();
        let in_phase = |p: CtaPhase| -> Vec<u32> {
            self.ctas
                .iter()
                .flatten()
                .filter(|c| c.phase == p)
                .map(|c| c.cta)
                .collect()
        };
        let _ = write!(
            out,
            "CTAs resident {:?}, {} done; RT queue {:?}; next timer {:?}",
            in_phase(CtaPhase::Running),
            self.done.len(),
            self.ready,
            self.next_timer()
        );
        if self.budget.is_some() {
            let _ = write!(
                out,
                "; virtualization: suspending {:?}, suspended {:?}, resuming {:?}, ready to \
                 resume (ids) {:?}, {} rays in flight, {} threads reserved, {} suspends, {} \
                 resumes",
                in_phase(CtaPhase::Suspending),
                in_phase(CtaPhase::Suspended),
                in_phase(CtaPhase::Resuming),
                self.resumable,
                self.in_flight,
                self.reserved,
                self.suspends,
                self.resumes
            );
        }
        out += "; warps:";
        for (i, w) in self.warps.iter().enumerate() {
            if let Some(w) = w {
                let live = w.threads.iter().flatten().count();
                let _ = write!(out, " [{i}: {:?}, {live} threads]", w.state);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A warp's worth of empty threads (`PathThread`s need a scene; these tests only move
    /// warps between states).
    fn warps(n: usize) -> Vec<Vec<Option<PathThread>>> {
        vec![vec![None]; n]
    }

    #[test]
    fn virtual_ids_without_virtualization_are_the_lowest_free_slots() {
        let mut sm = Sm::new(2, 2);
        sm.launch(7, warps(2), 10);
        sm.launch(8, warps(2), 10);
        assert_eq!(sm.free_slots(), 0);
        assert_eq!(sm.launchable(), 0);
        // Warps without threads end at their first timer; both CTAs retire.
        assert!(sm.run_timers(10).is_empty());
        assert!(sm.is_idle());
        assert_eq!(sm.done.len(), 2);
        assert_eq!(sm.free_slots(), 2);
        sm.launch(9, warps(2), 20);
        assert_eq!(sm.warp(0).map(|w| w.cta_id), Some(0));
        assert!(sm.warp(2).is_none());
    }

    #[test]
    fn launchable_respects_the_ray_budget() {
        let sm = Sm::new(4, 2).with_virtualization(RayBudget {
            max_rays: 128,
            cta_threads: 64,
            policy: VirtualizationConfig::default(),
        });
        assert_eq!(sm.launchable(), 2);
        assert!(sm.can_dispatch(true));
        assert!(!sm.can_dispatch(false));
        let sm = Sm::new(4, 2);
        assert_eq!(sm.launchable(), 4);
    }
}
