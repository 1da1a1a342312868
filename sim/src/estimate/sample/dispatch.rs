//! A CTA-level model of the GPU's dispatch, for the sampled tier's extrapolation: which SM gets
//! which CTA and when the last SM finishes, from each CTA's work in the functional profile.
//!
//! Each SM holds up to `resident` CTAs at once and shares its throughput equally among them
//! (processor sharing: a CTA with `w` units of work left and `n` residents finishes after
//! `n x w` time units if nothing changes). CTAs are handed out in CTA order: first round-robin
//! over the SMs until every SM is full, as the CTA scheduler fills an idle GPU, then each to the
//! SM whose CTA finished first (ties to the lower SM). The model's makespan is in work units;
//! only ratios of makespans are used (see [`makespan_ratio`]), so the throughput cancels.

/// The CTAs an SM holds at once in `cfg`'s design: its CTA slots, or with ray virtualization as
/// many as its ray budget (`hw.max_rays`) covers.
pub fn resident_ctas(cfg: &crate::model::config::SimConfig) -> usize {
    let slots = (cfg.gpu.max_ctas_per_sm as usize)
        .min(cfg.gpu.max_warps_per_sm as usize / cfg.warps_per_cta().max(1) as usize)
        .max(1);
    if cfg.mode.virtualization {
        slots.max(cfg.hw.max_rays as usize / cfg.gpu.threads_per_cta.max(1) as usize)
    } else {
        slots
    }
}

/// The CTAs `cfg`'s GPU holds at once: [`resident_ctas`] on every SM.
pub fn held_at_once(cfg: &crate::model::config::SimConfig) -> usize {
    resident_ctas(cfg) * cfg.gpu.sms as usize
}

/// Whether `cfg`'s design holds a frame of `ctas` CTAs at once.
pub fn holds_every_cta(cfg: &crate::model::config::SimConfig, ctas: usize) -> bool {
    held_at_once(cfg) >= ctas
}

/// The makespan (in work units) of `work` (per CTA, in dispatch order) on `sms` SMs holding up
/// to `resident` CTAs each.
pub fn makespan(work: &[f64], sms: usize, resident: usize) -> f64 {
    let (sms, resident) = (sms.max(1), resident.max(1));
    // Per SM: its clock and its residents' remaining work.
    let mut clock = vec![0.0f64; sms];
    let mut residents: Vec<Vec<f64>> = vec![Vec::new(); sms];
    let mut next = 0;
    // The initial fill: round-robin, one CTA per SM per pass.
    'fill: for _ in 0..resident {
        for r in residents.iter_mut() {
            let Some(&w) = work.get(next) else {
                break 'fill;
            };
            r.push(w);
            next += 1;
        }
    }
    let mut end = 0.0f64;
    loop {
        // The SM whose first resident finishes first, and that resident.
        let mut best: Option<(f64, usize, usize)> = None;
        for (s, r) in residents.iter().enumerate() {
            let Some((i, &min)) = r.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)) else {
                continue;
            };
            let t = clock[s] + min * r.len() as f64;
            if best.is_none_or(|(bt, _, _)| t < bt) {
                best = Some((t, s, i));
            }
        }
        let Some((t, s, i)) = best else {
            break;
        };
        clock[s] = t;
        end = end.max(t);
        // The finishing CTA leaves (removed by position, so every step retires one CTA even
        // when rounding leaves its remaining work a hair above zero), with any that finish
        // with it; the others have done as much work as it had left.
        let r = &mut residents[s];
        let done = r.swap_remove(i);
        for w in r.iter_mut() {
            *w -= done;
        }
        let eps = done.abs() * 1e-12;
        r.retain(|&w| w > eps);
        while r.len() < resident && next < work.len() {
            r.push(work[next]);
            next += 1;
        }
    }
    end
}

/// The factor that carries a scale model's cycles to the full GPU's under the dispatch model:
/// the full GPU's makespan (all CTAs `full` on `sms` SMs) over the scale model's (the sample's
/// CTAs `sample` on `scale_sms` SMs), both holding `resident` CTAs per SM.
pub fn makespan_ratio(
    full: &[f64],
    sms: usize,
    sample: &[f64],
    scale_sms: usize,
    resident: usize,
) -> f64 {
    let scale = makespan(sample, scale_sms, resident);
    if scale > 0.0 {
        makespan(full, sms, resident) / scale
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_work_divides_over_the_sms() {
        // 8 equal CTAs, 4 SMs, 2 at a time: every SM runs 2, sharing: makespan 2 x 1 = 2.
        assert!((makespan(&[1.0; 8], 4, 2) - 2.0).abs() < 1e-9);
        // 1 SM holding one at a time: the sum.
        assert!((makespan(&[1.0, 2.0, 3.0], 1, 1) - 6.0).abs() < 1e-9);
        // Half the SMs for half the CTAs: the same makespan, ratio 1.
        let r = makespan_ratio(&[1.0; 64], 16, &[1.0; 8], 2, 4);
        assert!((r - 1.0).abs() < 1e-9, "{r}");
    }

    #[test]
    fn a_static_stripe_shows_its_slowest_sm_and_dispatch_rebalances() {
        // 2 SMs, CTA work alternating 3, 1: round-robin binding puts all the 3s on SM 0.
        let work: Vec<f64> = (0..8).map(|i| if i % 2 == 0 { 3.0 } else { 1.0 }).collect();
        // Everything resident at once (virtualization): SM 0 holds 12 units, SM 1 holds 4.
        assert!((makespan(&work, 2, 4) - 12.0).abs() < 1e-9);
        // One at a time: SM 1 finishes its 1s early and takes the later CTAs.
        assert!(makespan(&work, 2, 1) < 12.0 - 1e-9);
    }

    #[test]
    fn large_costs_that_round_to_no_progress_still_finish() {
        // Costs in cycles (about a million per SM) drawn as a run's measured CTA costs are:
        // subtracting what finished from each resident leaves remainders of a few 1e-11 that
        // the SM's clock (about 1e6) cannot advance by. The model once looped forever on such
        // a remainder; now each step retires a CTA, and the result lies between the bounds of
        // perfect balance (total / SMs) and one SM doing everything.
        let mut rng = crate::model::splitmix::SplitMix64::new(1);
        let work: Vec<f64> = (0..1024)
            .map(|_| f64::from(rng.range(100.0, 5000.0)) * f64::from(rng.range(10.0, 61.0)))
            .collect();
        let total: f64 = work.iter().sum();
        for (sms, resident) in [(16, 16), (16, 4), (1, 64), (16, 64)] {
            let m = makespan(&work, sms, resident);
            assert!(m >= total / sms as f64 * (1.0 - 1e-9) && m <= total * (1.0 + 1e-9));
        }
    }
}
