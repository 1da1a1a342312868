//! Stripe samples, for a design whose SMs hold every CTA of the frame at once (e.g. VTQ at
//! 256x256: 64 CTAs per SM under ray virtualization). The CTA scheduler's round-robin fill then
//! binds CTA `c` to SM `c mod gpu.sms` for the whole run, so each SM runs a fixed *stripe* of
//! CTAs and the frame ends with the slowest stripe. A stratified sample mixes the stripes and
//! measures an average SM; an SM's time, though, is decided by whether its stripe's BVH working
//! set fits its L1 (docs/accuracy.md: on lands the SMs finish between 148k and 862k cycles for
//! stripes of near-equal node fetches). So the replicates simulate whole stripes instead — the
//! ones the profile predicts slowest — and the estimate is the slowest of them.
//!
//! The prediction ranks stripes by the product of their footprint (distinct BVH lines, the
//! working set) and their node fetches (the work), each relative to the frame's mean: the
//! stripe with the largest product first, ties to the lower stripe. Measured on the issue's
//! scenes at 256x256 under VTQ, the slowest stripe was among the first two so ranked in 9 of 10
//! (docs/accuracy.md).

use super::profile::StripeWork;

/// The stripes in the order they are sampled: by footprint times fetches, largest first (ties
/// to the lower stripe).
pub fn ranked(stripes: &[StripeWork]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..stripes.len() as u32).collect();
    let key = |s: u32| {
        let w = &stripes[s as usize];
        // Exact in u128: footprint and fetches each below 2^64.
        u128::from(w.lines) * u128::from(w.fetches)
    };
    order.sort_by(|&a, &b| key(b).cmp(&key(a)).then(a.cmp(&b)));
    order
}

/// The CTAs (ascending) of each replicate's stripes: replicate `r` of `replicates` runs the
/// stripes ranked `r x per_replicate ..(r + 1) x per_replicate` ([`ranked`]) of a frame of
/// `ctas` CTAs, on a scale model of `per_replicate` SMs (its round-robin fill gives each of its
/// SMs one stripe). Errors when the replicates need more stripes than the GPU has.
pub fn stripe_samples(
    stripes: &[StripeWork],
    ctas: usize,
    per_replicate: usize,
    replicates: usize,
) -> Result<Vec<Vec<u32>>, String> {
    let sms = stripes.len();
    if per_replicate * replicates > sms {
        return Err(format!(
            "stripe sampling simulates whole stripes, one per SM: {replicates} replicates of \
             {per_replicate} SM(s) need {} stripes but the GPU has {sms} (use fraction x \
             replicates <= 1, or sample.stripes = false for stratified samples)",
            per_replicate * replicates
        ));
    }
    let order = ranked(stripes);
    Ok(order
        .chunks(per_replicate.max(1))
        .take(replicates)
        .map(|chosen| {
            (0..ctas as u32)
                .filter(|&c| chosen.contains(&(c % sms as u32)))
                .collect()
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stripe(fetches: u64, lines: u64) -> StripeWork {
        StripeWork {
            rays: 1,
            fetches,
            lines,
        }
    }

    #[test]
    fn the_largest_working_set_times_work_comes_first() {
        let s = [
            stripe(100, 10),
            stripe(90, 30),
            stripe(200, 10),
            stripe(100, 10),
        ];
        // Products 1000, 2700, 2000, 1000: stripe 1, 2, then the tie 0, 3 in order.
        assert_eq!(ranked(&s), vec![1, 2, 0, 3]);
    }

    #[test]
    fn replicates_take_whole_stripes_in_rank_order() {
        let s = [stripe(1, 1), stripe(5, 5), stripe(3, 3), stripe(4, 4)];
        // 10 CTAs on 4 SMs: stripe 1 is CTAs 1, 5, 9; stripe 3 is 3, 7; stripe 2 is 2, 6.
        let one = stripe_samples(&s, 10, 1, 2).unwrap();
        assert_eq!(one, vec![vec![1, 5, 9], vec![3, 7]]);
        let two = stripe_samples(&s, 10, 2, 2).unwrap();
        assert_eq!(two, vec![vec![1, 3, 5, 7, 9], vec![0, 2, 4, 6, 8]]);
        let err = stripe_samples(&s, 10, 2, 3).unwrap_err();
        assert!(err.contains("need 6 stripes but the GPU has 4"), "{err}");
    }
}
