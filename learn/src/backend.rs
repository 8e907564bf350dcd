//! The compute backend.

use burn::prelude::Device;

/// Where the networks run. Flex (Burn's pure-Rust CPU backend) is the default
/// and the only one with the hand-written kernels ([`crate::kernels`]); ndarray
/// (deprecated in Burn 0.22) runs Burn's own layers and is a cargo feature.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Burn's ndarray backend, with the `ndarray` cargo feature.
    #[cfg(feature = "ndarray")]
    NdArray,
    Flex,
}

impl Backend {
    #[allow(deprecated)] // Device::ndarray is deprecated in Burn 0.22.
    pub fn device(&self) -> Device {
        match self {
            #[cfg(feature = "ndarray")]
            Backend::NdArray => Device::ndarray(),
            Backend::Flex => Device::flex(),
        }
    }

    pub fn as_str(&self) -> &'static str {
        match self {
            #[cfg(feature = "ndarray")]
            Backend::NdArray => "ndarray",
            Backend::Flex => "flex",
        }
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            #[cfg(feature = "ndarray")]
            "ndarray" => Ok(Backend::NdArray),
            #[cfg(not(feature = "ndarray"))]
            "ndarray" => Err(
                "the ndarray backend is not compiled in; build with `--features ndarray` (e.g. `cargo run --release --features ndarray -- …`)".into(),
            ),
            "flex" => Ok(Backend::Flex),
            _ => Err(format!("unknown backend `{s}`; allowed: flex, ndarray")),
        }
    }
}
