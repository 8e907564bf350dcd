//! Counter-based random streams.
//!
//! Every random draw of the world comes from a stream keyed by
//! `(seed, purpose, a, b)` — for example `(seed, SPAWN, fish, respawn count)` —
//! so a fish's draws do not depend on which thread handles it or on how many
//! other fish drew before it: serial and parallel runs give the same bits. The
//! generator is SplitMix64 (Steele, Lea & Flood 2014), written here so the
//! streams stay the same whatever version of `rand` the workspace uses.

/// What a stream is for; keeps streams of different purposes apart.
#[derive(Clone, Copy, Debug)]
#[repr(u64)]
pub enum Purpose {
    /// Per-fish traits: body scale, light preferences.
    Traits = 1,
    /// Which fish are dominant.
    Dominance = 2,
    /// Initial placement and respawns.
    Spawn = 3,
    /// Chase starts.
    Chase = 4,
    /// Random actions of the random policy.
    Policy = 5,
    /// Exploration noise of a learned Gaussian policy.
    Exploration = 6,
    /// Minibatch shuffles of a trainer.
    Shuffle = 7,
    /// Replay sampling and the reparameterisation noise of off-policy updates.
    Replay = 8,
    /// Which fish act as the policy's mirror image (`mirrored_share`).
    Handedness = 9,
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

#[inline]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A SplitMix64 stream.
#[derive(Clone, Debug)]
pub struct Stream {
    state: u64,
}

impl Stream {
    /// The stream for `(seed, purpose, a, b)`.
    pub fn new(seed: u64, purpose: Purpose, a: u64, b: u64) -> Self {
        let mut s = mix(seed.wrapping_add(GOLDEN));
        s = mix(s ^ (purpose as u64).wrapping_mul(GOLDEN));
        s = mix(s ^ a.wrapping_add(GOLDEN));
        s = mix(s ^ b.wrapping_mul(0xD6E8_FEB8_6659_FD93).wrapping_add(1));
        Self { state: s }
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix(self.state)
    }

    /// Uniform in [0, 1) with 24 random bits.
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in [lo, hi).
    #[inline]
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.uniform()
    }

    /// A standard normal draw (Box–Muller).
    #[inline]
    pub fn normal(&mut self) -> f32 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }

    /// Uniform integer in [0, n).
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        (((self.next_u64() >> 32) * n as u64) >> 32) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(Stream::new(7, Purpose::Spawn, 3, 0), |s, _| {
                Some(s.next_u64())
            })
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(Stream::new(7, Purpose::Spawn, 3, 0), |s, _| {
                Some(s.next_u64())
            })
            .collect();
        let c: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(Stream::new(7, Purpose::Spawn, 4, 0), |s, _| {
                Some(s.next_u64())
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(Stream::new(7, Purpose::Chase, 3, 0).next_u64(), a[0]);
    }

    #[test]
    fn uniform_is_roughly_uniform() {
        let mut s = Stream::new(1, Purpose::Policy, 0, 0);
        let n = 100_000;
        let mut hist = [0usize; 10];
        for _ in 0..n {
            let u = s.uniform();
            assert!((0.0..1.0).contains(&u));
            hist[(u * 10.0) as usize] += 1;
        }
        for h in hist {
            assert!((h as f64 - 10_000.0).abs() < 500.0, "{hist:?}");
        }
        assert!((0..1000).all(|_| s.below(3) < 3));
        let z: Vec<f32> = (0..n).map(|_| s.normal()).collect();
        let mean = z.iter().sum::<f32>() / n as f32;
        let var = z.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / n as f32;
        assert!(
            mean.abs() < 0.02 && (var - 1.0).abs() < 0.03,
            "{mean} {var}"
        );
    }
}
