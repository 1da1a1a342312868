//! Axes as a careful author draws them: a linear axis from round number to round number with
//! about five to eight ticks of one step (1, 2 or 5 times a power of ten), or a fixed range (a
//! rate from 0 to 100%); a logarithmic axis with ticks at the decades and a light minor grid at
//! 2 and 5 times each. Tick labels are plain numbers: as many decimals as the step needs and a
//! comma between thousands (`0.5`, `100`, `1,000`, `10,000`), never `1000.0`.
//!
//! Charts draw in axis space: a value `v` is at [`Axis::to`]`(v)`, its logarithm on a
//! logarithmic axis, so plotters only ever sees a linear axis.

/// One axis of a chart: its range, ticks and minor grid lines (values, not positions).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Lowest value shown.
    pub lo: f64,
    /// Highest value shown.
    pub hi: f64,
    /// Logarithmic (base 10).
    pub log: bool,
    /// The labelled ticks, ascending.
    pub ticks: Vec<f64>,
    /// The minor grid lines between the ticks, ascending.
    pub minor: Vec<f64>,
    /// Decimals of every tick label (linear axes; a logarithmic axis labels each tick with the
    /// decimals it needs).
    decimals: usize,
}

/// The intervals between ticks a linear axis aims for at least (it takes at most 8).
const MIN_TICKS: f64 = 5.0;

/// Decimals of a tick step: the fewest that write it exactly (`0.25` → 2, `10` → 0), at most 6.
fn decimals_of(step: f64) -> usize {
    (0..6)
        .find(|&d| {
            let scaled = step * 10f64.powi(d as i32);
            (scaled - scaled.round()).abs() < 1e-6 * scaled.abs().max(1.0)
        })
        .unwrap_or(6)
}

/// A round step for a linear axis spanning `span` with about [`MIN_TICKS`] to 8 intervals: 1,
/// 2 or 5 times a power of ten (so labels need no more decimals than the power).
fn nice_step(span: f64) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / MIN_TICKS;
    let power = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|&s| span / s <= 8.0 + 1e-9)
        .unwrap_or(10.0 * power)
}

/// The multiples of `step` from `lo` to `hi` (both within a rounding error).
fn multiples(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

impl Axis {
    /// A linear axis that holds `lo..=hi` and zero, and ends on ticks.
    pub fn linear(lo: f64, hi: f64) -> Axis {
        let (lo, hi) = finite_or(lo, hi, (0.0, 1.0));
        let (lo, hi) = (lo.min(0.0), hi.max(0.0));
        let hi = if hi > lo { hi } else { lo + 1.0 };
        let step = nice_step(hi - lo);
        // A value within a rounding error of a tick is on it.
        let lo = (lo / step + 1e-9).floor() * step;
        let hi = (hi / step - 1e-9).ceil() * step;
        Axis::fixed_with_step(lo, hi, step)
    }

    /// A linear axis of exactly `lo..=hi` (e.g. 0 to 100 for a rate in percent), ticks at round
    /// steps inside it.
    pub fn fixed(lo: f64, hi: f64) -> Axis {
        let (lo, hi) = finite_or(lo, hi, (0.0, 1.0));
        let hi = if hi > lo { hi } else { lo + 1.0 };
        Axis::fixed_with_step(lo, hi, nice_step(hi - lo))
    }

    /// The category axis of a bar chart of `n` categories: category `i` centred on `i`, a tick
    /// each.
    pub fn categories(n: usize) -> Axis {
        Axis {
            lo: -0.5,
            hi: n.max(1) as f64 - 0.5,
            log: false,
            ticks: (0..n).map(|i| i as f64).collect(),
            minor: Vec::new(),
            decimals: 0,
        }
    }

    /// A linear axis of `lo..=hi` with ticks at the multiples of `step`.
    fn fixed_with_step(lo: f64, hi: f64, step: f64) -> Axis {
        Axis {
            lo,
            hi,
            log: false,
            ticks: multiples(lo, hi, step),
            minor: Vec::new(),
            decimals: decimals_of(step),
        }
    }

    /// A logarithmic axis that holds the positive `lo..=hi` with a little room, from and to 1,
    /// 2 or 5 times a power of ten. Ticks at the decades (and at 2 and 5 times them too when it
    /// spans less than two decades); minor grid lines at 2 and 5 times the decades that are not
    /// ticks (none beyond six decades).
    pub fn log(lo: f64, hi: f64) -> Axis {
        let (lo, hi) = finite_or(lo, hi, (1.0, 10.0));
        let lo = if lo > 0.0 {
            lo
        } else {
            hi.abs().max(1e-300) / 10.0
        };
        let hi = hi.max(lo);
        let lo = round_125(lo / 1.2, false);
        let hi = round_125(hi * 1.2, true);
        let decades = (hi / lo).log10();
        let all: Vec<f64> = (lo.log10().floor() as i32..=hi.log10().ceil() as i32)
            .flat_map(|e| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(e)))
            .filter(|v| *v >= lo * (1.0 - 1e-9) && *v <= hi * (1.0 + 1e-9))
            .collect();
        let decade = |v: &f64| (v.log10() - v.log10().round()).abs() < 1e-9;
        let (ticks, minor) = if decades < 2.0 {
            (all, Vec::new())
        } else if decades <= 6.0 {
            all.into_iter().partition(decade)
        } else {
            (all.into_iter().filter(decade).collect(), Vec::new())
        };
        Axis {
            lo,
            hi,
            log: true,
            ticks,
            minor,
            decimals: 0,
        }
    }

    /// A value's position on the axis (its base-10 logarithm on a logarithmic axis).
    pub fn to(&self, v: f64) -> f64 {
        if self.log {
            v.max(f64::MIN_POSITIVE).log10()
        } else {
            v
        }
    }

    /// The positions of the axis' ends.
    pub fn span(&self) -> (f64, f64) {
        (self.to(self.lo), self.to(self.hi))
    }

    /// The label of the tick at position `pos`.
    pub fn label_at(&self, pos: f64) -> String {
        if self.log {
            let v = 10f64.powf(pos);
            tick_label(v, decimals_of(round_sig(v)))
        } else {
            tick_label(pos, self.decimals)
        }
    }
}

/// `(lo, hi)` when both are finite, else `fallback`.
fn finite_or(lo: f64, hi: f64, fallback: (f64, f64)) -> (f64, f64) {
    if lo.is_finite() && hi.is_finite() {
        (lo, hi)
    } else {
        fallback
    }
}

/// `v` to 9 significant digits (the value a tick's position stands for).
fn round_sig(v: f64) -> f64 {
    if v == 0.0 {
        return 0.0;
    }
    let scale = 10f64.powi(8 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

/// The next 1, 2 or 5 times a power of ten at or above (`up`) or at or below `v` (positive).
fn round_125(v: f64, up: bool) -> f64 {
    let e = v.log10().floor() as i32;
    let candidates = (e - 1..=e + 1).flat_map(|e| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(e)));
    if up {
        candidates
            .filter(|c| *c >= v * (1.0 - 1e-9))
            .fold(f64::INFINITY, f64::min)
    } else {
        candidates
            .filter(|c| *c <= v * (1.0 + 1e-9))
            .fold(0.0, f64::max)
    }
}

/// A tick label: `v` with `decimals` decimals and a comma between thousands (`1,000`, `0.25`,
/// `-2,500.5`); never `-0`.
pub fn tick_label(v: f64, decimals: usize) -> String {
    let text = format!("{:.*}", decimals, v.abs());
    let (int, frac) = text.split_once('.').unwrap_or((&text, ""));
    let mut grouped = String::new();
    for (i, c) in int.chars().enumerate() {
        if i > 0 && (int.len() - i) % 3 == 0 {
            grouped.push(',');
        }
        grouped.push(c);
    }
    let zero = text.chars().all(|c| c == '0' || c == '.');
    let sign = if v < 0.0 && !zero { "-" } else { "" };
    if frac.is_empty() {
        format!("{sign}{grouped}")
    } else {
        format!("{sign}{grouped}.{frac}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(a: &Axis) -> Vec<String> {
        a.ticks.iter().map(|&t| a.label_at(a.to(t))).collect()
    }

    #[test]
    fn tick_labels_are_plain_numbers() {
        assert_eq!(tick_label(1000.0, 0), "1,000");
        assert_eq!(tick_label(10000.0, 0), "10,000");
        assert_eq!(tick_label(1234567.0, 0), "1,234,567");
        assert_eq!(tick_label(100.0, 0), "100");
        assert_eq!(tick_label(0.5, 1), "0.5");
        assert_eq!(tick_label(-2500.5, 1), "-2,500.5");
        assert_eq!(tick_label(-0.0001, 1), "0.0");
        assert_eq!(decimals_of(0.25), 2);
        assert_eq!(decimals_of(2.5), 1);
        assert_eq!(decimals_of(20.0), 0);
    }

    #[test]
    fn a_log_axis_reads_100_1000_10000_with_a_sparse_minor_grid() {
        // Figure 5's concurrent rays.
        let a = Axis::log(32.0, 65536.0);
        assert_eq!(labels(&a), ["100", "1,000", "10,000", "100,000"]);
        assert!(a.lo <= 32.0 && a.hi >= 65536.0);
        // 2 and 5 times each decade: at most two minor lines per decade.
        let decades = (a.hi / a.lo).log10();
        assert!(
            a.minor.len() as f64 <= 2.0 * decades.ceil(),
            "{:?}",
            a.minor
        );
        assert!(a.minor.contains(&50.0) && a.minor.contains(&2000.0));
        // Below one: as many decimals as the value needs.
        let b = Axis::log(0.27, 160.0);
        assert_eq!(labels(&b), ["1", "10", "100"]);
        let c = Axis::log(0.002, 0.9);
        assert_eq!(labels(&c), ["0.001", "0.01", "0.1", "1"]);
        // Less than two decades: 2 and 5 labelled too, no minor grid.
        let d = Axis::log(3.0, 40.0);
        assert_eq!(labels(&d), ["2", "5", "10", "20", "50"]);
        assert!(d.minor.is_empty());
    }

    #[test]
    fn linear_axes_end_on_round_ticks_and_fixed_ones_where_told() {
        let a = Axis::linear(0.0, 2.55);
        assert_eq!((a.lo, a.hi), (0.0, 3.0));
        assert_eq!(
            labels(&a),
            ["0.0", "0.5", "1.0", "1.5", "2.0", "2.5", "3.0"]
        );
        let rate = Axis::fixed(0.0, 100.0);
        assert_eq!((rate.lo, rate.hi), (0.0, 100.0));
        assert_eq!(rate.ticks.first(), Some(&0.0));
        assert_eq!(rate.ticks.last(), Some(&100.0));
        assert!(labels(&rate).iter().all(|l| !l.contains('.')));
        let unit = Axis::fixed(0.0, 1.0);
        assert_eq!(labels(&unit), ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
        // Negative values: the axis goes below zero, ticks stay round.
        let n = Axis::linear(-3.2, 10.4);
        assert!(n.lo <= -3.2 && n.hi >= 10.4 && n.ticks.contains(&0.0));
        assert!((5..=9).contains(&n.ticks.len()), "{:?}", n.ticks);
        // Nothing to show, or an empty range: a unit axis.
        let e = Axis::linear(f64::INFINITY, f64::NEG_INFINITY);
        assert_eq!((e.lo, e.hi), (0.0, 1.0));
        let f = Axis::fixed(5.0, 5.0);
        assert_eq!((f.lo, f.hi, f.ticks.len()), (5.0, 6.0, 6));
        let g = Axis::log(7.0, 7.0);
        assert!(g.lo < 7.0 && g.hi > 7.0 && !g.ticks.is_empty());
    }
}
