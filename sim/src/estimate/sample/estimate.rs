//! Estimates with 95% confidence intervals from independent replicates: the mean of the
//! replicates' values and Student's t interval over their spread.

use serde::Serialize;

/// Two-sided 95% quantiles of Student's t distribution for 1..=30 degrees of freedom.
const T975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];

/// The 97.5% quantile of Student's t with `dof` degrees of freedom (`dof >= 1`; the normal
/// quantile 1.96 above 30, where the table's error is under 2%).
pub fn t975(dof: usize) -> f64 {
    T975.get(dof.saturating_sub(1)).copied().unwrap_or(1.96)
}

/// An estimate and its 95% confidence interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The estimate (mean over replicates).
    pub value: f64,
    /// Half-width of the 95% interval (`None` from a single replicate: no spread to measure).
    pub half_width: Option<f64>,
}

impl Estimate {
    /// The mean of `values` with Student's t interval (empty `values`: 0, no interval).
    pub fn of(values: &[f64]) -> Estimate {
        let n = values.len();
        if n == 0 {
            return Estimate {
                value: 0.0,
                half_width: None,
            };
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let half_width = (n > 1).then(|| {
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            t975(n - 1) * (var / n as f64).sqrt()
        });
        Estimate {
            value: mean,
            half_width,
        }
    }

    /// The interval `(low, high)`, if there is one.
    pub fn interval(&self) -> Option<(f64, f64)> {
        self.half_width.map(|h| (self.value - h, self.value + h))
    }

    /// Whether `x` lies in the interval (false without one).
    pub fn contains(&self, x: f64) -> bool {
        self.interval().is_some_and(|(lo, hi)| lo <= x && x <= hi)
    }

    /// `value ± half-width` with `digits` decimals (`value` alone without an interval).
    pub fn display(&self, digits: usize) -> String {
        match self.half_width {
            Some(h) => format!("{:.*} ± {:.*}", digits, self.value, digits, h),
            None => format!("{:.*}", digits, self.value),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_t_interval() {
        let e = Estimate::of(&[10.0, 12.0, 11.0, 13.0]);
        assert_eq!(e.value, 11.5);
        // s = sqrt(5/3), t(3) = 3.182: 3.182 * sqrt(5/3) / 2.
        let h = e.half_width.unwrap();
        assert!((h - 3.182 * (5.0f64 / 3.0).sqrt() / 2.0).abs() < 1e-12);
        assert!(e.contains(11.5 + h) && !e.contains(11.5 + h * 1.01));
        let one = Estimate::of(&[5.0]);
        assert_eq!((one.value, one.half_width), (5.0, None));
        assert!(!one.contains(5.0));
        assert_eq!(t975(100), 1.96);
        assert_eq!(e.display(1), "11.5 ± 2.1");
    }
}
