//! The diagonal Gaussian policy with a state-independent log-std.
//!
//! `log π(a) = −Σ_k [ (a_k − μ_k)² / (2 σ_k²) + log σ_k + ½ log 2π ]`,
//! `H = Σ_k [ ½ + ½ log 2π + log σ_k ]`. Actions are sampled from the
//! Gaussian, clipped to [−1, 1] for the environment, and the log-probability
//! is that of the unclipped sample (as ML-Agents and CleanRL do).

use burn::prelude::*;

const HALF_LOG_2PI: f32 = 0.918_938_5;

/// Log-probability `[B]` of `action` `[B, K]` under N(`mean` `[B, K]`, exp(`log_std` `[K]`)).
pub fn log_prob(mean: Tensor<2>, log_std: Tensor<1>, action: Tensor<2>) -> Tensor<1> {
    let log_std: Tensor<2> = log_std.unsqueeze();
    let z = (action - mean) / log_std.clone().exp();
    let per_dim = z.powf_scalar(2.0).mul_scalar(-0.5) - log_std - HALF_LOG_2PI;
    per_dim.sum_dim(1).flatten(0, 1)
}

/// Entropy of the Gaussian (a scalar tensor `[1]`).
pub fn entropy(log_std: Tensor<1>) -> Tensor<1> {
    (log_std + 0.5 + HALF_LOG_2PI).sum()
}

/// `log_prob` for one sample in plain floats (rollout bookkeeping).
pub fn log_prob_f32(mean: &[f32], log_std: &[f32], action: &[f32]) -> f32 {
    mean.iter()
        .zip(log_std)
        .zip(action)
        .map(|((&m, &s), &a)| {
            let z = (a - m) / s.exp();
            -0.5 * z * z - s - HALF_LOG_2PI
        })
        .sum()
}

/// Entropy in plain floats.
pub fn entropy_f32(log_std: &[f32]) -> f32 {
    log_std.iter().map(|s| s + 0.5 + HALF_LOG_2PI).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dev() -> Device {
        Device::flex()
    }

    /// Hand-computed: μ = (0, 1, −0.5), log σ = (0, ln 2, −ln 2), a = (1, 1, 0):
    /// z = (1, 0, 1) → −½(1 + 0 + 1) − (0 + 0.693147 − 0.693147) − 3 · 0.918939
    /// = −1 − 2.756816 = −3.756816.
    #[test]
    fn log_prob_by_hand() {
        let ln2 = 2f32.ln();
        let mean = Tensor::<2>::from_data(TensorData::new(vec![0.0f32, 1.0, -0.5], [1, 3]), &dev());
        let log_std = Tensor::<1>::from_data(TensorData::new(vec![0.0f32, ln2, -ln2], [3]), &dev());
        let action =
            Tensor::<2>::from_data(TensorData::new(vec![1.0f32, 1.0, 0.0], [1, 3]), &dev());
        let lp = log_prob(mean, log_std.clone(), action)
            .into_data()
            .try_into_vec::<f32>()
            .unwrap();
        assert!((lp[0] + 3.756_816).abs() < 1e-5, "{lp:?}");
        assert!(
            (log_prob_f32(&[0.0, 1.0, -0.5], &[0.0, ln2, -ln2], &[1.0, 1.0, 0.0]) + 3.756_816)
                .abs()
                < 1e-5
        );
        // Entropy: 3 · (0.5 + 0.918939) + (0 + ln 2 − ln 2) = 4.256816.
        let h = entropy(log_std).into_scalar::<f32>();
        assert!((h - 4.256_816).abs() < 1e-5, "{h}");
        assert!((entropy_f32(&[0.0, ln2, -ln2]) - 4.256_816).abs() < 1e-5);
    }
}
