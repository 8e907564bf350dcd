//! Small tensor helpers: flat buffers in and out of Burn, forced
//! initialisation, and gradient norms for global-norm clipping.

use burn::module::{Module, ModuleVisitor, Param, ParamId};
use burn::optim::GradientsParams;
use burn::prelude::*;
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS};

/// `n` stacked grids `[n, 18, 20, 34]` from a flat buffer (zero-copy).
pub fn tensor4(data: Vec<f32>, n: usize, dev: &Device) -> Tensor<4> {
    Tensor::from_data(
        TensorData::new(data, [n, STACKED_CHANNELS, EL_CELLS, AZ_CELLS]),
        dev,
    )
}

/// A `[n, width]` matrix from a flat row-major buffer (zero-copy).
pub fn tensor2(data: Vec<f32>, n: usize, width: usize, dev: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(data, [n, width]), dev)
}

/// A vector `[n]`.
pub fn tensor1(data: Vec<f32>, dev: &Device) -> Tensor<1> {
    let n = data.len();
    Tensor::from_data(TensorData::new(data, [n]), dev)
}

/// A tensor's values, row-major.
pub fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_into_vec::<f32>().expect("an f32 tensor")
}

/// Burn initialises parameters lazily; touch them all so a seeded init is reproducible.
pub struct ForceInit;
impl ModuleVisitor for ForceInit {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        let _ = p.val();
    }
}

/// The parameters of a part of a model, by id and rank, for global-norm clipping.
#[derive(Clone, Debug, Default)]
pub struct ParamIds(Vec<(ParamId, usize)>);

impl ParamIds {
    /// Every float parameter of `module`, appended.
    pub fn with<M: Module>(mut self, module: &M) -> Self {
        module.visit(&mut self);
        self
    }

    /// One parameter, appended.
    pub fn with_param<const D: usize>(mut self, p: &Param<Tensor<D>>) -> Self {
        self.0.push((p.id, D));
        self
    }
}

impl ModuleVisitor for ParamIds {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        self.0.push((p.id, D));
    }
}

fn sum_squares(g: Option<Vec<f32>>) -> f64 {
    g.map_or(0.0, |v| v.iter().map(|&x| x as f64 * x as f64).sum())
}

/// The global L2 norm of the gradients of `ids`.
pub fn grad_norm(grads: &GradientsParams, ids: &ParamIds) -> f32 {
    let mut sum = 0.0;
    for &(id, rank) in &ids.0 {
        sum += match rank {
            1 => sum_squares(grads.get::<1>(id).map(to_vec)),
            2 => sum_squares(grads.get::<2>(id).map(to_vec)),
            3 => sum_squares(grads.get::<3>(id).map(to_vec)),
            4 => sum_squares(grads.get::<4>(id).map(to_vec)),
            r => unreachable!("parameters of rank {r}"),
        };
    }
    sum.sqrt() as f32
}

fn scale<const D: usize>(grads: &mut GradientsParams, id: ParamId, s: f32) {
    if let Some(g) = grads.remove::<D>(id) {
        grads.register::<D>(id, g.mul_scalar(s));
    }
}

/// Scale the gradients of `ids` so that their global norm is at most
/// `max_norm` (PyTorch's `clip_grad_norm_`, ε 1e−6); returns the norm before clipping.
pub fn clip_grad_norm(grads: &mut GradientsParams, ids: &ParamIds, max_norm: f32) -> f32 {
    let norm = grad_norm(grads, ids);
    if norm > max_norm {
        let s = max_norm / (norm + 1e-6);
        for &(id, rank) in &ids.0 {
            match rank {
                1 => scale::<1>(grads, id, s),
                2 => scale::<2>(grads, id, s),
                3 => scale::<3>(grads, id, s),
                4 => scale::<4>(grads, id, s),
                r => unreachable!("parameters of rank {r}"),
            }
        }
    }
    norm
}
