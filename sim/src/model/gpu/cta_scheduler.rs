//! The CTA scheduler: cuts the image into pixel tiles, one raygen CTA each, and hands them out
//! in pixel order (tiles row-major) to SMs with a free CTA slot, round-robin over the SMs. A
//! run may dispatch only a subset of the CTAs ([`CtaScheduler::with_subset`]: the sampled
//! tier's scale models), still in pixel order.
//! With ray virtualization, CTAs ready to resume take free slots of their SM first (paper
//! section 3.1: resuming CTAs have priority), and an SM takes a new CTA only while its ray
//! budget allows ([`crate::model::gpu::sm::Sm::launchable`]); the engine passes what is left here.

/// Shape of the pixel tile of one CTA and the order of CTAs over the image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CtaScheduler {
    width: u32,
    height: u32,
    tile_w: u32,
    tile_h: u32,
    tiles_x: u32,
    total: u32,
    /// The CTAs to dispatch, in order (`None`: all of them, `0..total`).
    subset: Option<Vec<u32>>,
    /// CTAs handed out so far.
    next: u32,
    /// SM to try first in the next round-robin pass.
    rr: usize,
}

impl CtaScheduler {
    /// CTAs of `threads_per_cta` threads over a `width` x `height` image: tiles as square as a
    /// power-of-two width dividing the thread count allows (8 x 8 for 64 threads); an image one
    /// row high (the `rays` workload's) in tiles one row high, so each CTA's threads take
    /// consecutive pixels.
    pub fn new(width: u32, height: u32, threads_per_cta: u32) -> Self {
        let mut tile_w = 1;
        while (tile_w * 2) * (tile_w * 2) <= threads_per_cta
            && threads_per_cta.is_multiple_of(tile_w * 2)
        {
            tile_w *= 2;
        }
        if height == 1 {
            tile_w = threads_per_cta;
        }
        let tile_h = threads_per_cta / tile_w;
        let tiles_x = width.div_ceil(tile_w);
        let tiles_y = height.div_ceil(tile_h);
        CtaScheduler {
            width,
            height,
            tile_w,
            tile_h,
            tiles_x,
            total: tiles_x * tiles_y,
            subset: None,
            next: 0,
            rr: 0,
        }
    }

    /// The same scheduler dispatching only `ctas` (sorted, distinct, each below
    /// [`total`](Self::total); checked by the caller), in that order.
    pub fn with_subset(self, ctas: Vec<u32>) -> Self {
        CtaScheduler {
            subset: Some(ctas),
            ..self
        }
    }

    /// The tile of CTA `cta`: `(column, row)` of tiles.
    pub fn tile(&self, cta: u32) -> (u32, u32) {
        (cta % self.tiles_x, cta / self.tiles_x)
    }

    /// The CTA of the tile at `(column, row)`, if the image has that tile.
    pub fn cta_at(&self, column: i64, row: i64) -> Option<u32> {
        let tiles_x = i64::from(self.tiles_x);
        let tiles_y = i64::from(self.total / self.tiles_x.max(1));
        ((0..tiles_x).contains(&column) && (0..tiles_y).contains(&row))
            .then(|| (row * tiles_x + column) as u32)
    }

    /// CTAs of the whole image.
    pub fn total(&self) -> u32 {
        self.total
    }

    /// CTAs this run dispatches.
    pub fn dispatched(&self) -> u32 {
        self.subset.as_ref().map_or(self.total, |s| s.len() as u32)
    }

    /// CTAs not handed out yet.
    pub fn pending(&self) -> u32 {
        self.dispatched() - self.next
    }

    /// The pixel of every thread of CTA `cta` (row-major within the tile); `None` for threads
    /// outside the image.
    pub fn pixels(&self, cta: u32) -> Vec<Option<u32>> {
        let (tx, ty) = self.tile(cta);
        (0..self.tile_w * self.tile_h)
            .map(|i| {
                let x = tx * self.tile_w + i % self.tile_w;
                let y = ty * self.tile_h + i / self.tile_w;
                (x < self.width && y < self.height).then_some(y * self.width + x)
            })
            .collect()
    }

    /// Hands out pending CTAs to SMs with room (`free[sm]` new CTAs each), round-robin from
    /// where the last pass stopped; returns `(sm, cta)` in hand-out order.
    pub fn dispatch(&mut self, free: &mut [u32]) -> Vec<(usize, u32)> {
        let mut out = Vec::new();
        let n = free.len();
        while self.next < self.dispatched() {
            let Some(sm) = (0..n).map(|k| (self.rr + k) % n).find(|&s| free[s] > 0) else {
                break;
            };
            free[sm] -= 1;
            let cta = self
                .subset
                .as_ref()
                .map_or(self.next, |s| s[self.next as usize]);
            out.push((sm, cta));
            self.next += 1;
            self.rr = (sm + 1) % n;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_every_pixel_once() {
        let s = CtaScheduler::new(20, 10, 64);
        assert_eq!((s.tile_w, s.tile_h), (8, 8));
        let mut seen = vec![0; 200];
        for cta in 0..s.total() {
            for p in s.pixels(cta).into_iter().flatten() {
                seen[p as usize] += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        assert_eq!(CtaScheduler::new(8, 8, 32).tile_w, 4);
    }

    #[test]
    fn dispatch_is_round_robin_over_free_slots() {
        let mut s = CtaScheduler::new(64, 64, 64);
        let mut free = vec![2, 0, 1];
        assert_eq!(s.dispatch(&mut free), vec![(0, 0), (2, 1), (0, 2)]);
        let mut free = vec![1, 1, 1];
        assert_eq!(s.dispatch(&mut free), vec![(1, 3), (2, 4), (0, 5)]);
    }

    #[test]
    fn a_subset_is_dispatched_in_its_order() {
        let mut s = CtaScheduler::new(64, 64, 64).with_subset(vec![2, 7, 9]);
        assert_eq!((s.total(), s.dispatched(), s.pending()), (64, 3, 3));
        let mut free = vec![1, 1];
        assert_eq!(s.dispatch(&mut free), vec![(0, 2), (1, 7)]);
        let mut free = vec![5, 5];
        assert_eq!(s.dispatch(&mut free), vec![(0, 9)]);
        assert_eq!(s.pending(), 0);
    }
}
