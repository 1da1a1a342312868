//! Stratified samples of a frame's CTAs: the CTAs — or runs of `sample.cluster` neighbouring
//! CTAs — sorted by their profiled work are cut into as many strata as the sample holds, and one
//! is drawn from each stratum, so every sample spreads over the whole range of work (cheap sky
//! tiles, expensive geometry tiles) in the frame's proportions. Draws are deterministic for a
//! seed and replicate.

use crate::model::splitmix::SplitMix64;

/// The CTAs (indices into `costs`, sorted ascending) of replicate `replicate`'s stratified
/// sample of `fraction` of them (at least one unit), drawn with `seed`, in units of `cluster`
/// consecutive CTAs (the last unit may be shorter): the units, sorted by their summed cost, are
/// cut into as many strata as the sample holds units, and one unit is drawn from each. With
/// `fraction` 1 it is every CTA.
pub fn stratified_sample(
    costs: &[u64],
    fraction: f64,
    seed: u64,
    replicate: u32,
    cluster: usize,
) -> Vec<u32> {
    let total = costs.len();
    if total == 0 {
        return Vec::new();
    }
    let cluster = cluster.clamp(1, total);
    let units = total.div_ceil(cluster);
    // The CTAs of unit `u`.
    let span = |u: usize| u * cluster..((u + 1) * cluster).min(total);
    let n = ((units as f64 * fraction).round() as usize).clamp(1, units);
    let mut order: Vec<(u64, u32)> = (0..units)
        .map(|u| (costs[span(u)].iter().sum(), u as u32))
        .collect();
    order.sort_unstable();
    let mut rng =
        SplitMix64::new(seed ^ (u64::from(replicate) + 1).wrapping_mul(0xd1b5_4a32_d192_ed03));
    let mut out: Vec<u32> = (0..n)
        .flat_map(|i| {
            let (lo, hi) = (i * units / n, (i + 1) * units / n);
            let u = order[lo + rng.below_exact((hi - lo) as u64) as usize].1 as usize;
            span(u).map(|c| c as u32)
        })
        .collect();
    out.sort_unstable();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_cta_per_stratum_deterministically() {
        let costs: Vec<u64> = (0..64).map(|i| (i * 37 % 64) as u64).collect();
        let a = stratified_sample(&costs, 0.125, 7, 0, 1);
        assert_eq!(a.len(), 8);
        assert_eq!(a, stratified_sample(&costs, 0.125, 7, 0, 1));
        assert_ne!(a, stratified_sample(&costs, 0.125, 7, 1, 1));
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        // Stratum i holds the CTAs of cost 8i..8i+7: one of each.
        let mut strata: Vec<u64> = a.iter().map(|&c| costs[c as usize] / 8).collect();
        strata.sort_unstable();
        assert_eq!(strata, (0..8).collect::<Vec<u64>>());
        let all = stratified_sample(&costs, 1.0, 7, 3, 1);
        assert_eq!(all, (0..64).collect::<Vec<u32>>());
        assert_eq!(stratified_sample(&costs, 0.001, 1, 0, 1).len(), 1);
    }

    #[test]
    fn clusters_are_runs_of_consecutive_ctas_drawn_by_their_work() {
        // 66 CTAs in 17 units of 4 (the last of 2); a unit's work is its CTAs' sum.
        let costs: Vec<u64> = (0..66).map(|i| ((i / 4) * 7 % 17) as u64).collect();
        let a = stratified_sample(&costs, 0.25, 3, 0, 4);
        assert_eq!(a, stratified_sample(&costs, 0.25, 3, 0, 4));
        assert_ne!(a, stratified_sample(&costs, 0.25, 3, 1, 4));
        // round(17 units / 4) = 4 units, each whole: 4 consecutive CTAs from a multiple of 4 (the
        // last unit, CTAs 64 and 65, has two).
        let units: Vec<u32> = a.iter().map(|c| c / 4).collect();
        let mut distinct = units.clone();
        distinct.dedup();
        assert_eq!(distinct.len(), 4);
        for u in &distinct {
            let n = units.iter().filter(|x| *x == u).count();
            assert_eq!(n, if *u == 16 { 2 } else { 4 });
        }
        // One unit per stratum of units sorted by work: the strata of 17 units by 4 draws hold
        // units 0..4, 4..8, 8..12, 12..17 of that order.
        let mut order: Vec<(u64, u32)> = (0..17u32)
            .map(|u| {
                (
                    costs[(u as usize * 4)..((u as usize + 1) * 4).min(66)]
                        .iter()
                        .sum(),
                    u,
                )
            })
            .collect();
        order.sort_unstable();
        let rank = |u: u32| order.iter().position(|&(_, x)| x == u).unwrap();
        let mut strata: Vec<usize> = distinct
            .iter()
            .map(|&u| {
                let r = rank(u);
                (0..4)
                    .find(|i| r >= i * 17 / 4 && r < (i + 1) * 17 / 4)
                    .unwrap()
            })
            .collect();
        strata.sort_unstable();
        assert_eq!(strata, vec![0, 1, 2, 3]);
        // The whole frame, whatever the unit, also where the short last unit makes the units
        // more than the CTAs over the unit round to (65 CTAs: 16 units of 4 and one of 1).
        assert_eq!(
            stratified_sample(&costs, 1.0, 3, 0, 4),
            (0..66).collect::<Vec<u32>>()
        );
        assert_eq!(
            stratified_sample(&costs[..65], 1.0, 3, 0, 4),
            (0..65).collect::<Vec<u32>>()
        );
        // A unit larger than the frame is the frame.
        assert_eq!(
            stratified_sample(&costs, 0.1, 3, 0, 100),
            (0..66).collect::<Vec<u32>>()
        );
    }
}
