//! Stratified samples of a frame's CTAs: the CTAs sorted by their profiled work are cut into as
//! many strata of consecutive CTAs as the sample holds, and one CTA is drawn from each stratum,
//! so every sample spreads over the whole range of work (cheap sky tiles, expensive geometry
//! tiles) in the frame's proportions. Draws are deterministic for a seed and replicate.

use crate::model::splitmix::SplitMix64;

/// The CTAs (indices into `costs`, sorted ascending) of replicate `replicate`'s stratified
/// sample of `fraction` of them (at least one), drawn with `seed`. With `fraction` 1 it is every
/// CTA.
pub fn stratified_sample(costs: &[u64], fraction: f64, seed: u64, replicate: u32) -> Vec<u32> {
    let total = costs.len();
    if total == 0 {
        return Vec::new();
    }
    let n = ((total as f64 * fraction).round() as usize).clamp(1, total);
    let mut order: Vec<u32> = (0..total as u32).collect();
    order.sort_by_key(|&c| (costs[c as usize], c));
    let mut rng =
        SplitMix64::new(seed ^ (u64::from(replicate) + 1).wrapping_mul(0xd1b5_4a32_d192_ed03));
    let mut out: Vec<u32> = (0..n)
        .map(|i| {
            let (lo, hi) = (i * total / n, (i + 1) * total / n);
            order[lo + rng.below_exact((hi - lo) as u64) as usize]
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
        let a = stratified_sample(&costs, 0.125, 7, 0);
        assert_eq!(a.len(), 8);
        assert_eq!(a, stratified_sample(&costs, 0.125, 7, 0));
        assert_ne!(a, stratified_sample(&costs, 0.125, 7, 1));
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        // Stratum i holds the CTAs of cost 8i..8i+7: one of each.
        let mut strata: Vec<u64> = a.iter().map(|&c| costs[c as usize] / 8).collect();
        strata.sort_unstable();
        assert_eq!(strata, (0..8).collect::<Vec<u64>>());
        let all = stratified_sample(&costs, 1.0, 7, 3);
        assert_eq!(all, (0..64).collect::<Vec<u32>>());
        assert_eq!(stratified_sample(&costs, 0.001, 1, 0).len(), 1);
    }
}
