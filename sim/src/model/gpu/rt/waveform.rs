//! Waveforms of a simulation window (`vtq sim --vcd`): the hdl blocks of one SM's RT unit,
//! cycle by cycle, written as VCD ([`vtq_hdl::trace::VcdStream`]) while the simulation runs.
//!
//! What is recorded is exactly what the blocks see: each cycle's inputs, its outputs and the
//! registers at the start of the cycle. The baseline and prefetch designs record the RT unit
//! (scope `rt_unit`); the queues design records the treelet RT unit's ports and the wiring's
//! registers (scope `treelet_rt_unit`) and each of its children in its own scope below it
//! (`treelet_rt_unit.rt`, `.ctl`, `.ct`, `.qt`: RT unit, treelet controller, count table,
//! queue table), observed through the block's probe ([`TreeletRtUnitCache::probe`]). Each
//! scope holds `inputs`, `outputs` and `regs`.
//!
//! Every cycle of the window is recorded. The simulator skips cycles in which the RT unit only
//! counts (it catches them up with `skip`); inside the window the port steps those cycles one
//! by one with the idle inputs it would have seen, which the blocks define to be the same as the
//! skip (tested in `vtq-hdl`), so results do not change. Outside the window nothing is
//! recorded and nothing costs: the port only checks whether it has a probe.
//!
//! [`TreeletRtUnitCache::probe`]: vtq_hdl::treelet_rt_unit::TreeletRtUnitCache::probe

use std::fs::File;
use std::io::BufWriter;
use std::ops::Range;
use std::path::PathBuf;

use vtq_hdl::rt_unit::{RtUnit, RtUnitRegs};
use vtq_hdl::trace::{BlockCycle, ScopedSignals, TraceError, VcdStream};
use vtq_hdl::treelet_rt_unit::{ProbeCycle, TreeletRtUnitInputs, TreeletRtUnitOutputs};
use vtq_hdl::{Block, Signal, Signals};

use super::hardware::RtHardware;
use super::{RtPort, Shell};
use crate::model::gpu::datapath::BvhDatapath;
use crate::model::gpu::error::SimError;

/// The longest window (cycles) a waveform may cover.
pub const MAX_WINDOW_CYCLES: u64 = 1_000_000;

/// Where and what to record as a waveform: SM `sm`'s RT unit over `cycles` (end exclusive),
/// written to `path`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VcdWindow {
    /// The VCD file.
    pub path: PathBuf,
    /// The SM.
    pub sm: usize,
    /// The cycles, end exclusive.
    pub cycles: Range<u64>,
}

/// Parses a window `A..B` (cycles `A` to `B - 1`): `A < B` and at most
/// [`MAX_WINDOW_CYCLES`] cycles.
pub fn parse_cycles(spec: &str) -> Result<Range<u64>, String> {
    let bad = |why: &str| format!("--vcd-cycles '{spec}': {why}");
    let (a, b) = spec
        .split_once("..")
        .ok_or_else(|| bad("expected A..B, e.g. 400000..402000 (B exclusive)"))?;
    let num = |s: &str, what: &str| {
        s.trim()
            .replace('_', "")
            .parse::<u64>()
            .map_err(|_| bad(&format!("{what} '{s}' is not a cycle number")))
    };
    let (a, b) = (num(a, "start")?, num(b, "end")?);
    if a >= b {
        return Err(bad(
            "the window is empty: its start must be below its end (B exclusive)",
        ));
    }
    if b - a > MAX_WINDOW_CYCLES {
        return Err(bad(&format!(
            "{} cycles; a window holds at most {MAX_WINDOW_CYCLES}",
            b - a
        )));
    }
    Ok(a..b)
}

/// A waveform written by a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WaveformSummary {
    /// The VCD file.
    pub path: PathBuf,
    /// The SM.
    pub sm: usize,
    /// The cycles recorded, end exclusive.
    pub cycles: Range<u64>,
    /// Of those, the cycles the simulator would have skipped (the RT unit only counting), stepped
    /// with idle inputs for the waveform.
    pub idle_steps: u64,
}

/// The waveform of a window being written: the VCD goes to a temporary file beside `path`
/// ([`crate::model::atomic_file::temp_path`]) and is renamed to `path` once every cycle of the window
/// is in ([`Waveform::finish`]).
#[derive(Debug)]
pub struct Waveform {
    sm: usize,
    window: Range<u64>,
    path: PathBuf,
    partial: PathBuf,
    stream: VcdStream<BufWriter<File>>,
    /// The first recording error (nothing more is recorded after it).
    error: Option<TraceError>,
    /// Cycles stepped only for the waveform ([`WaveformSummary::idle_steps`]).
    idle_steps: u64,
}

impl Waveform {
    /// Starts the waveform of `window` (whose SM and cycles are already checked), with a
    /// header comment `comment`.
    pub fn create(window: &VcdWindow, comment: &str) -> Result<Self, SimError> {
        let partial = crate::model::atomic_file::temp_path(&window.path);
        let file = File::create(&partial)
            .map_err(|e| SimError::Waveform(format!("cannot create {}: {e}", partial.display())))?;
        let top = format!("sm{}", window.sm);
        Ok(Waveform {
            sm: window.sm,
            window: window.cycles.clone(),
            path: window.path.clone(),
            stream: VcdStream::new(BufWriter::new(file), &top, window.cycles.start)
                .with_comment(comment),
            partial,
            error: None,
            idle_steps: 0,
        })
    }

    /// Whether cycle `c` is in the window.
    pub fn covers(&self, c: u64) -> bool {
        self.window.contains(&c)
    }

    /// Records the next cycle's scopes (an error is kept for [`Waveform::finish`]).
    fn record(&mut self, scopes: &[ScopedSignals]) {
        if self.error.is_none() {
            if let Err(e) = self.stream.record(scopes) {
                self.error = Some(e);
            }
        }
    }

    /// Records a cycle of the RT unit (baseline and prefetch designs).
    #[cold]
    #[inline(never)]
    pub(super) fn record_rt_unit(&mut self, cycle: BlockCycle) {
        let mut scopes = Vec::with_capacity(3);
        cycle.push_scopes("rt_unit", &mut scopes);
        self.record(&scopes);
    }

    /// Records a cycle of the treelet RT unit (queues design): its ports, the wiring's registers
    /// and its children's cycle as the probe saw it.
    #[cold]
    #[inline(never)]
    pub(super) fn record_treelet(
        &mut self,
        inputs: &TreeletRtUnitInputs,
        outputs: &TreeletRtUnitOutputs,
        probe: Option<ProbeCycle>,
    ) {
        let Some(probe) = probe else {
            self.error.get_or_insert_with(|| {
                TraceError::Content("the treelet RT unit's probe saw no cycle".into())
            });
            return;
        };
        let mut scopes = Vec::with_capacity(15);
        let top = BlockCycle {
            inputs: inputs.signals(),
            outputs: outputs.signals(),
            regs: probe.glue,
        };
        top.push_scopes("treelet_rt_unit", &mut scopes);
        for (name, child) in probe.children {
            child.push_scopes(&format!("treelet_rt_unit.{name}"), &mut scopes);
        }
        self.record(&scopes);
    }

    /// Ends the waveform of a run of `cycles` cycles: an error if the window reaches past the
    /// run's end or a cycle could not be recorded (the partial file is removed); otherwise the
    /// file is complete and takes its name.
    pub fn finish(self, cycles: u64) -> Result<WaveformSummary, SimError> {
        let Waveform {
            sm,
            idle_steps,
            window,
            path,
            partial,
            stream,
            error,
        } = self;
        let fail = |msg: String| {
            let _ = std::fs::remove_file(&partial);
            Err(SimError::Waveform(msg))
        };
        if window.end > cycles {
            return fail(format!(
                "the window {}..{} reaches past the end of the run ({cycles} cycles, 0..{cycles}); \
                 choose --vcd-cycles within it",
                window.start, window.end
            ));
        }
        let recorded = stream.cycles() as u64;
        if let Some(e) = error {
            return fail(format!("recording cycle {}: {e}", window.start + recorded));
        }
        if recorded != window.end - window.start {
            return fail(format!(
                "{recorded} of the window's {} cycles were recorded",
                window.end - window.start
            ));
        }
        if let Err(e) = stream.finish() {
            return fail(format!("writing {}: {e}", partial.display()));
        }
        std::fs::rename(&partial, &path).map_err(|e| {
            SimError::Waveform(format!(
                "renaming {} to {}: {e}",
                partial.display(),
                path.display()
            ))
        })?;
        Ok(WaveformSummary {
            path,
            sm,
            cycles: window,
            idle_steps,
        })
    }

    /// Removes the partial file of a run that failed.
    pub fn abandon(self) {
        let _ = std::fs::remove_file(&self.partial);
    }
}

/// The RT unit's registers as trace signals (kept out of the simulator's hot path).
#[cold]
#[inline(never)]
pub(super) fn rt_unit_regs(unit: &RtUnit<BvhDatapath<'_>>, regs: &RtUnitRegs) -> Vec<Signal> {
    unit.reg_signals(regs)
}

impl RtPort<'_> {
    /// Records SM `sm`'s RT unit into `waveform` over its window.
    pub fn attach_waveform(&mut self, waveform: Waveform) {
        self.shell.waveform = Some(Box::new(waveform));
    }

    /// The waveform, if one is attached.
    pub fn take_waveform(&mut self) -> Option<Waveform> {
        self.shell.waveform.take().map(|w| *w)
    }

    /// Catches the registers up to the start of cycle `now` over idle cycles, stepping those in
    /// the waveform's window one by one with idle inputs (as `skip` would advance them) and
    /// recording them.
    #[cold]
    #[inline(never)]
    pub(super) fn catch_up_recorded(&mut self, now: u64) {
        let Some(window) = self.shell.waveform.as_ref().map(|w| w.window.clone()) else {
            return self.skip_to(now);
        };
        let lo = self.shell.at.max(window.start).min(now);
        let hi = now.min(window.end).max(lo);
        self.skip_to(lo);
        for c in lo..hi {
            self.idle_step(c);
        }
        self.skip_to(now);
        // A step's dry run may know more than a skip: the wake cycle follows the registers.
        self.shell.wake = self.shell.at.saturating_add(self.idle_cycles());
    }

    /// One idle cycle `c` (`c == at`) stepped and recorded: no warp offered, no response, no
    /// ray record (the queue table's spill FIFO head is presented as always).
    fn idle_step(&mut self, c: u64) {
        debug_assert_eq!(c, self.shell.at, "idle steps follow the registers");
        if self.shell.waveform.is_some() {
            self.observe_warps(1);
        }
        self.shell.at = c + 1;
        let Some(w) = self.shell.waveform.as_mut() else {
            return;
        };
        w.idle_steps += 1;
        self.hw.idle_step(&mut self.shell.stats, w, c);
    }
}

impl Shell<'_> {
    /// Whether cycle `c` is recorded.
    pub(super) fn recording(&self, c: u64) -> bool {
        self.waveform.as_ref().is_some_and(|w| w.covers(c))
    }
}
