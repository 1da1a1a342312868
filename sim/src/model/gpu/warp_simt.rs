//! SIMT efficiency averaged per RT-unit warp ([`WarpSimt`]), the way the RT-unit model of the
//! paper's simulator lineage averages it (docs/fidelity.md gives the source and its caveat),
//! beside vtq's own measure averaged per warp cycle.
//!
//! vtq's `simt_efficiency` is the ratio of sums: traversing lanes over `warp_size` x RT-unit
//! warp cycles, every warp cycle weighing the same. That RT-unit model computes one ratio per
//! warp when the warp leaves the unit — the cycles each of its threads spent before its trace
//! completed, over `warp_size` x the warp's cycles in the unit — and reports the mean over warps
//! (`rt_total_simt_efficiency / rt_total_warps`), every warp weighing the same: a warp held for
//! thousands of cycles by one straggler counts as much as a short full one. Here a warp is a
//! warp-buffer slot's occupancy from the cycle it holds a warp to the cycle it is empty again,
//! cut where lanes are appended (a warp-repacking fill: paper section 4.5 terminates the
//! repacked warp and fills a new one), and its threads are its traversing lanes, counted as
//! `simt_efficiency` counts them (start-of-cycle state, skipped idle cycles included).

/// One RT unit's warps, followed slot by slot.
#[derive(Debug, Clone, PartialEq)]
pub struct WarpSimt {
    /// Per slot the open warp's cycles, lane-cycles and lanes in its last cycle (0 cycles: no
    /// warp open).
    open: Vec<(u64, u64, u32)>,
    /// Sum over closed warps of lane-cycles / (warp size x cycles).
    sum: f64,
    /// Closed warps.
    warps: u64,
    /// Lanes of a full warp.
    warp_size: u32,
}

impl WarpSimt {
    /// Follows a warp buffer of `slots` slots of `warp_size` lanes.
    pub fn new(slots: usize, warp_size: u32) -> Self {
        WarpSimt {
            open: vec![(0, 0, 0); slots],
            sum: 0.0,
            warps: 0,
            warp_size,
        }
    }

    /// Adds `n` cycles in which the slots hold `lanes` (per slot: traversing lanes, `None` for
    /// an empty slot), closing the warps that left or were refilled since the last call.
    pub fn observe(&mut self, n: u64, lanes: impl Iterator<Item = Option<u32>>) {
        let warp_size = self.warp_size;
        for (o, l) in self.open.iter_mut().zip(lanes) {
            let (cycles, lane_cycles, last) = *o;
            match l {
                Some(l) => {
                    if l > last && cycles > 0 {
                        self.sum += lane_cycles as f64 / (warp_size as f64 * cycles as f64);
                        self.warps += 1;
                        *o = (n, n * u64::from(l), l);
                    } else {
                        *o = (cycles + n, lane_cycles + n * u64::from(l), l);
                    }
                }
                None if cycles > 0 => {
                    self.sum += lane_cycles as f64 / (warp_size as f64 * cycles as f64);
                    self.warps += 1;
                    *o = (0, 0, 0);
                }
                None => {}
            }
        }
    }

    /// The sum over closed warps of their SIMT efficiency, and the number of warps (a warp
    /// still open at the end of a run is not counted: a finished run has none).
    pub fn totals(&self) -> (f64, u64) {
        (self.sum, self.warps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_warp_weighs_the_same() {
        let mut w = WarpSimt::new(2, 4);
        // Slot 0: a full warp for 10 cycles, then 1 lane for 90 (one straggler), then empty.
        w.observe(10, [Some(4)].into_iter());
        w.observe(90, [Some(1)].into_iter());
        w.observe(1, [None].into_iter());
        let (sum, warps) = w.totals();
        assert_eq!(warps, 1);
        // (40 + 90) / (4 x 100).
        assert!((sum - 0.325).abs() < 1e-12, "{sum}");
        // A short full warp in slot 1 then weighs as much as the long one.
        w.observe(5, [None, Some(4)].into_iter());
        w.observe(1, [None, None].into_iter());
        let (sum, warps) = w.totals();
        assert_eq!(warps, 2);
        assert!((sum / warps as f64 - (0.325 + 1.0) / 2.0).abs() < 1e-12);
    }

    #[test]
    fn an_appended_fill_starts_a_new_warp() {
        let mut w = WarpSimt::new(1, 4);
        w.observe(3, [Some(2)].into_iter());
        w.observe(2, [Some(1)].into_iter());
        // Lanes appended: the 5-cycle warp closes, a new one starts.
        w.observe(4, [Some(4)].into_iter());
        assert_eq!(w.totals().1, 1);
        w.observe(1, [None].into_iter());
        let (sum, warps) = w.totals();
        assert_eq!(warps, 2);
        // (6 + 2) / (4 x 5) + 16 / (4 x 4).
        assert!((sum - (0.4 + 1.0)).abs() < 1e-12, "{sum}");
    }
}
