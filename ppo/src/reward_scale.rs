//! Reward scaling by the running standard deviation of the discounted return
//! (gym's `NormalizeReward`, as CleanRL): the thesis' rewards span −300 to
//! +100 per decision.

use serde::{Deserialize, Serialize};

/// Running mean and variance (Chan et al.'s parallel update).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunningMeanStd {
    pub mean: f64,
    pub var: f64,
    pub count: f64,
}

impl Default for RunningMeanStd {
    fn default() -> Self {
        Self {
            mean: 0.0,
            var: 1.0,
            count: 1e-4,
        }
    }
}

impl RunningMeanStd {
    /// Fold a batch of values in.
    pub fn update(&mut self, xs: &[f64]) {
        if xs.is_empty() {
            return;
        }
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        let delta = mean - self.mean;
        let total = self.count + n;
        self.mean += delta * n / total;
        let m2 = self.var * self.count + var * n + delta * delta * self.count * n / total;
        self.var = m2 / total;
        self.count = total;
    }

    pub fn std(&self) -> f64 {
        (self.var + 1e-8).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn running_variance_matches_the_batch_formula() {
        let xs: Vec<f64> = (0..100)
            .map(|i| (i as f64 * 0.37).sin() * 5.0 + 2.0)
            .collect();
        let mut r = RunningMeanStd {
            mean: 0.0,
            var: 0.0,
            count: 0.0,
        };
        for c in xs.chunks(7) {
            r.update(c);
        }
        let mean = xs.iter().sum::<f64>() / 100.0;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 100.0;
        assert!((r.mean - mean).abs() < 1e-9 && (r.var - var).abs() < 1e-9);
    }
}
