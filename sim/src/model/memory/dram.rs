//! [`Dram`]: DRAM as `dram_channels` channels (addresses interleaved by
//! `dram_interleave_bytes`), each a [`DramChannel`] with a fixed latency and a byte-exact share
//! of the bandwidth. One channel (the default) is the whole bandwidth, first come first served.
//!
//! The channel moves `bytes_per_cycle` bytes per core cycle. Its time is counted in byte slots
//! (`cycle * bytes_per_cycle + offset`), so bandwidths that are not a multiple of the transfer
//! size are exact rather than rounded up to whole cycles. A transfer of `b` bytes arriving at
//! cycle `a` occupies slots `[s, s + b)` with `s = max(a * bytes_per_cycle, next_free)`, and
//! `next_free` becomes `s + b` (a "next free" register: transfers are served in arrival order,
//! which the memory system guarantees is also call order). The transfer starts in cycle
//! `start = floor(s / bytes_per_cycle)` and its data is back at `start + latency`.
//!
//! When `bytes_per_cycle` divides `b` this is exactly a channel busy `b / bytes_per_cycle`
//! cycles per transfer with `start = max(arrival, next_free_cycle)`.

/// Start and completion cycles of one transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DramGrant {
    /// Cycle the transfer starts (arrival plus queueing).
    pub start: u64,
    /// Cycle its data is back (`start + latency`).
    pub done: u64,
}

/// One DRAM channel: fixed latency, bandwidth-limited, first come first served.
///
/// A channel with a `num / den` share of a `bytes_per_cycle` bandwidth counts time in slots of
/// `1 / (bytes_per_cycle x num)` cycle and a transfer of `b` bytes takes `b x den` of them,
/// which is exact for any share.
#[derive(Debug, Clone)]
pub struct DramChannel {
    latency: u64,
    /// Slots per cycle (`bytes_per_cycle x num`).
    bytes_per_cycle: u64,
    /// Slots a byte takes (`den`).
    slot_divisor: u64,
    /// First free slot.
    next_free: u128,
}

impl DramChannel {
    /// An idle channel with all of `bytes_per_cycle`. `bytes_per_cycle` must be positive
    /// (checked by [`MemConfig::validate`](super::MemConfig::validate)).
    pub fn new(latency: u32, bytes_per_cycle: u32) -> Self {
        DramChannel::with_share(latency, bytes_per_cycle, [1, 1])
    }

    /// An idle channel of `bytes_per_cycle * share[0] / share[1]` bytes per cycle (`share`
    /// validated: `0 < share[0] <= share[1]` for a scale model's part of the GPU, or
    /// `[1, channels]` for one of several channels).
    pub fn with_share(latency: u32, bytes_per_cycle: u32, share: [u64; 2]) -> Self {
        DramChannel {
            latency: u64::from(latency),
            bytes_per_cycle: u64::from(bytes_per_cycle.max(1)) * share[0].max(1),
            slot_divisor: share[1].max(1),
            next_free: 0,
        }
    }

    /// Queues a transfer of `bytes` arriving at cycle `arrival`; arrivals must not decrease
    /// from call to call.
    pub fn schedule(&mut self, arrival: u64, bytes: u32) -> DramGrant {
        let bpc = u128::from(self.bytes_per_cycle);
        let slot = (u128::from(arrival) * bpc).max(self.next_free);
        self.next_free = slot + u128::from(bytes) * u128::from(self.slot_divisor);
        // slot / bpc <= max(arrival, previous end / bpc): fits in u64 for any reachable cycle.
        let start = u64::try_from(slot / bpc).unwrap_or(u64::MAX);
        DramGrant {
            start,
            done: start.saturating_add(self.latency),
        }
    }

    /// First cycle in which a new transfer could start without queueing.
    pub fn next_free_cycle(&self) -> u64 {
        let bpc = u128::from(self.bytes_per_cycle);
        u64::try_from(self.next_free.div_ceil(bpc)).unwrap_or(u64::MAX)
    }
}

/// DRAM: its channels and how addresses map onto them.
#[derive(Debug, Clone)]
pub struct Dram {
    channels: Vec<DramChannel>,
    /// log2 of the interleaving granularity in bytes.
    interleave_shift: u32,
}

impl Dram {
    /// Idle DRAM of `channels` channels sharing `bytes_per_cycle x share[0] / share[1]` (the
    /// GPU's share of the bandwidth, `[1, 1]` unless a scale model) equally, consecutive
    /// `interleave_bytes` (a power of two) of the address space in consecutive channels.
    pub fn new(
        latency: u32,
        bytes_per_cycle: u32,
        share: [u32; 2],
        channels: u32,
        interleave_bytes: u32,
    ) -> Self {
        let n = channels.max(1);
        let channel_share = [
            u64::from(share[0].max(1)),
            u64::from(share[1].max(1)) * u64::from(n),
        ];
        Dram {
            channels: (0..n)
                .map(|_| DramChannel::with_share(latency, bytes_per_cycle, channel_share))
                .collect(),
            interleave_shift: interleave_bytes.max(1).trailing_zeros(),
        }
    }

    /// Queues a transfer of `bytes` at byte address `addr` arriving at cycle `arrival` on its
    /// channel; arrivals must not decrease from call to call.
    pub fn schedule(&mut self, arrival: u64, addr: u64, bytes: u32) -> DramGrant {
        let n = self.channels.len() as u64;
        let channel = ((addr >> self.interleave_shift) % n) as usize;
        self.channels[channel].schedule(arrival, bytes)
    }

    /// First cycle in which every channel could start a new transfer without queueing.
    pub fn next_free_cycle(&self) -> u64 {
        self.channels
            .iter()
            .map(DramChannel::next_free_cycle)
            .max()
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_channel_dram_is_the_channel() {
        let mut a = DramChannel::new(10, 12);
        let mut d = Dram::new(10, 12, [1, 1], 1, 256);
        for (i, addr) in [0u64, 256, 512, 0, 4096, 100].into_iter().enumerate() {
            let at = 5 + i as u64 / 2;
            assert_eq!(d.schedule(at, addr, 32), a.schedule(at, 32));
        }
        assert_eq!(d.next_free_cycle(), a.next_free_cycle());
    }

    #[test]
    fn channels_split_the_bandwidth_and_interleave_addresses() {
        // 2 channels of 8 B/cycle each (16 in all), 256 B interleaving.
        let mut d = Dram::new(10, 16, [1, 1], 2, 256);
        // Same channel (addresses 0 and 128): back to back at 8 B/cycle, 4 cycles per sector.
        assert_eq!(d.schedule(100, 0, 32).start, 100);
        assert_eq!(d.schedule(100, 128, 32).start, 104);
        // The other channel (256) is idle.
        assert_eq!(d.schedule(100, 256, 32).start, 100);
        // 512 is channel 0 again, behind the two.
        assert_eq!(d.schedule(100, 512, 32).start, 108);
        assert_eq!(d.next_free_cycle(), 112);
    }

    #[test]
    fn idle_channel_adds_only_latency() {
        let mut d = DramChannel::new(254, 328);
        assert_eq!(
            d.schedule(1000, 32),
            DramGrant {
                start: 1000,
                done: 1254
            }
        );
        // 32 of 328 bytes of cycle 1000 are used; the next sector still starts in 1000.
        assert_eq!(d.schedule(1000, 32).start, 1000);
        assert_eq!(d.schedule(5000, 32).start, 5000);
    }

    #[test]
    fn whole_cycle_transfers_queue_back_to_back() {
        // 8 B/cycle: a 32 B sector keeps the channel busy 4 cycles.
        let mut d = DramChannel::new(10, 8);
        let starts: Vec<u64> = (0..5).map(|_| d.schedule(100, 32).start).collect();
        assert_eq!(starts, vec![100, 104, 108, 112, 116]);
        assert_eq!(d.next_free_cycle(), 120);
        // A later arrival after the queue drained starts on arrival.
        assert_eq!(
            d.schedule(130, 32),
            DramGrant {
                start: 130,
                done: 140
            }
        );
    }

    #[test]
    fn fractional_bandwidth_is_exact() {
        // 12 B/cycle: sector i starts in cycle floor(32 i / 12) after arrival.
        let mut d = DramChannel::new(1, 12);
        for i in 0..12u64 {
            assert_eq!(d.schedule(7, 32).start, 7 + 32 * i / 12);
        }
        // 12 sectors = 384 B = exactly 32 cycles of bandwidth.
        assert_eq!(d.next_free_cycle(), 7 + 32);
    }

    #[test]
    fn a_share_of_the_bandwidth_is_exact() {
        // 328 B/cycle, 1/16 of it: 20.5 B/cycle; sector i starts at floor(32 i / 20.5).
        let mut d = DramChannel::with_share(1, 328, [1, 16]);
        for i in 0..41u64 {
            assert_eq!(d.schedule(0, 32).start, 32 * 2 * i / 41);
        }
        // 41 sectors = 1312 B = exactly 64 cycles at 20.5 B/cycle.
        assert_eq!(d.next_free_cycle(), 64);
        // The whole share is the plain channel.
        let (mut a, mut b) = (
            DramChannel::new(5, 12),
            DramChannel::with_share(5, 12, [3, 3]),
        );
        for t in [0u64, 0, 3, 3, 3, 40, 41] {
            assert_eq!(a.schedule(t, 32), b.schedule(t, 32));
        }
    }

    #[test]
    fn a_scale_models_share_splits_over_the_channels() {
        // 2 channels sharing 1/2 of 32 B/cycle: each 8 B/cycle, 4 cycles per sector.
        let mut d = Dram::new(10, 32, [1, 2], 2, 256);
        assert_eq!(d.schedule(0, 0, 32).start, 0);
        assert_eq!(d.schedule(0, 128, 32).start, 4);
        assert_eq!(d.schedule(0, 256, 32).start, 0);
        assert_eq!(d.next_free_cycle(), 8);
    }
}
