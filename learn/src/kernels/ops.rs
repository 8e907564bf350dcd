//! The kernels as Burn operations: a custom autodiff op whose forward runs
//! [`EncoderPack::forward`] / [`DensePack::forward_silu`] on the Flex
//! tensors' memory and whose backward step (registered in Burn's graph)
//! runs the hand-written backward and hands Burn the gradients of every
//! tracked input. On a device without autodiff the ops just run forward.
//!
//! Only the Flex backend has them: on another backend these functions return
//! `None` and the caller uses Burn's layers.

use super::conv::ConvPack;
use super::dense::DensePack;
use super::encoder::{EncoderPack, EncoderSaved, GridsRef};
use super::geometry::*;
use crate::frames::CompactGrids;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, NodeGuard, Ops, OpsKind};
use burn::backend::flex::FlexTensor;
use burn::backend::{Autodiff, Flex};
use burn::nn::conv::Conv2d;
use burn::nn::{Linear, PaddingConfig2d};
use burn::prelude::*;
use deepfoids_sensors::STACKED_LEN;
use std::borrow::Cow;
use std::sync::Arc;

type Ad = Autodiff<Flex>;
type AdTensor = burn::backend::tensor::FloatTensor<Ad>;

/// Stacked grids as an input of the encoder.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // a tensor handle; built once per batch
pub enum Grids {
    /// `[n, 18, 20, 34]` floats on the module's device (may require a gradient).
    Dense(Tensor<4>),
    /// Quantised stacks (never differentiated): what the experience buffers hold.
    Compact(Arc<CompactGrids>),
}

impl Grids {
    /// Observations in the batch.
    pub fn len(&self) -> usize {
        match self {
            Grids::Dense(t) => t.dims()[0],
            Grids::Compact(c) => c.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The grids as a dense tensor on `dev` (rebuilding quantised ones).
    pub fn to_tensor(&self, dev: &Device) -> Tensor<4> {
        match self {
            Grids::Dense(t) => t.clone(),
            Grids::Compact(c) => crate::tensor::tensor4(c.to_dense(), c.len(), dev),
        }
    }
}

/// A tensor's primitive: tracked by Burn's autodiff, or plain Flex.
enum Prim {
    Tracked(AdTensor),
    Plain(FlexTensor),
}

fn prim<const D: usize>(t: Tensor<D>) -> Option<Prim> {
    match t.clone().try_into_primitive::<Ad>() {
        Ok(p) => Some(Prim::Tracked(p)),
        Err(_) => t.try_into_primitive::<Flex>().ok().map(Prim::Plain),
    }
}

/// The autodiff graph nodes of inputs that [`prims`] found all tracked.
fn graph_nodes(prims: &[Prim]) -> Vec<NodeGuard> {
    prims
        .iter()
        .map(|p| match p {
            Prim::Tracked(t) => t.node(),
            Prim::Plain(_) => unreachable!("all tracked"),
        })
        .collect()
}

impl Prim {
    fn flex(&self) -> &FlexTensor {
        match self {
            Prim::Tracked(t) => t.primitive(),
            Prim::Plain(t) => t,
        }
    }
}

/// A Flex tensor's values, row-major.
fn values(t: &FlexTensor) -> Cow<'_, [f32]> {
    match t.as_slice::<f32>() {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(
            t.to_contiguous()
                .as_slice::<f32>()
                .expect("a contiguous f32 tensor")
                .to_vec(),
        ),
    }
}

/// `t` with its values laid out row-major (a cheap handle when they are).
fn contiguous(t: &FlexTensor) -> FlexTensor {
    if t.is_contiguous() {
        t.clone()
    } else {
        t.to_contiguous()
    }
}

fn flex(values: Vec<f32>, shape: &[usize]) -> FlexTensor {
    FlexTensor::from_data(TensorData::new(values, shape.to_vec()))
}

/// All inputs of an op: tracked (on an autodiff device) or all plain; `None`
/// if any lives on another backend.
fn prims(tensors: Vec<Tensor<1>>) -> Option<(Vec<Prim>, bool)> {
    let prims: Vec<Prim> = tensors.into_iter().map(prim).collect::<Option<_>>()?;
    let tracked = prims
        .iter()
        .filter(|p| matches!(p, Prim::Tracked(_)))
        .count();
    match tracked {
        0 => Some((prims, false)),
        n if n == prims.len() => Some((prims, true)),
        _ => None,
    }
}

/// The six parameters of a body's encoder, flattened, in op input order.
fn encoder_params(conv1: &Conv2d, conv2: &Conv2d, fc: &Linear) -> Option<[Tensor<1>; 6]> {
    let flat = |t: Tensor<4>| t.flatten::<1>(0, 3);
    Some([
        flat(conv1.weight.val()),
        conv1.bias.as_ref()?.val(),
        flat(conv2.weight.val()),
        conv2.bias.as_ref()?.val(),
        fc.weight.val().flatten::<1>(0, 1),
        fc.bias.as_ref()?.val(),
    ])
}

/// The encoder layers of one body, as the op takes them.
pub struct EncoderLayers<'a> {
    pub conv1: &'a Conv2d,
    pub conv2: &'a Conv2d,
    pub fc: &'a Linear,
    pub slope: f32,
}

/// What a grid input is inside the op's state.
#[derive(Clone, Debug)]
enum GridsData {
    Dense(FlexTensor),
    Compact(Arc<CompactGrids>),
}

impl GridsData {
    fn as_ref(&self) -> GridsRef<'_> {
        match self {
            GridsData::Dense(t) => GridsRef::Dense(t.as_slice::<f32>().expect("contiguous grids")),
            GridsData::Compact(c) => GridsRef::Compact(&c.bytes),
        }
    }
}

#[derive(Clone, Debug)]
struct EncoderState {
    pack: Arc<EncoderPack>,
    grids: GridsData,
    saved: Arc<EncoderSaved>,
}

#[derive(Debug)]
struct EncoderBackward<const N: usize>;

impl<const N: usize> Backward<Flex, N> for EncoderBackward<N> {
    type State = EncoderState;

    fn backward(self, ops: Ops<Self::State, N>, grads: &mut Gradients, _: &mut Checkpointer) {
        let st = ops.state;
        let dh = grads.consume::<Flex>(&ops.node);
        let dh = values(&dh);
        let grids = st.grids.as_ref();
        let input_grad = ops.parents[0].is_some();
        let (g, dx) = st.pack.backward(grids, &st.saved, &dh, input_grad);
        let n = grids.len();
        // Every input entered flattened (1-D): gradients are registered so.
        if let (Some(node), Some(dx)) = (&ops.parents[0], dx) {
            grads.register::<Flex>(node.id, flex(dx, &[n * STACKED_LEN]));
        }
        let hidden = st.pack.hidden;
        for b in 0..st.pack.k {
            let w1 = g.w1[b * C1 * PATCH1..(b + 1) * C1 * PATCH1].to_vec();
            let b1 = g.b1[b * C1..(b + 1) * C1].to_vec();
            let parts: [(Vec<f32>, usize); 6] = [
                (w1, C1 * PATCH1),
                (b1, C1),
                (g.w2[b].clone(), C2 * PATCH2),
                (g.b2[b].clone(), C2),
                (g.wfc[b].clone(), CONV_FLAT * hidden),
                (g.bfc[b].clone(), hidden),
            ];
            for (i, (v, len)) in parts.into_iter().enumerate() {
                if let Some(node) = &ops.parents[1 + 6 * b + i] {
                    grads.register::<Flex>(node.id, flex(v, &[len]));
                }
            }
        }
    }
}

/// The encoders of `bodies` on the same grids, side by side: `[n, K·hidden]`,
/// body `b` in columns `b·hidden..(b + 1)·hidden`. `None` unless every tensor
/// is on the Flex backend (with or without autodiff).
pub fn encode(bodies: &[EncoderLayers<'_>], grids: &Grids) -> Option<Tensor<2>> {
    encode_with(bodies, grids, None)
}

/// [`encode`] with conv 1 on the non-zeros when at most `sparse_below` of a
/// chunk's inputs is non-zero, quantised or f32 grids alike (0: always
/// im2col + GEMM; 1: always sparse; `None`: the defaults,
/// [`SPARSE_BELOW`](super::encoder::SPARSE_BELOW) and
/// [`SPARSE_BELOW_DENSE`](super::encoder::SPARSE_BELOW_DENSE)).
pub fn encode_with(
    bodies: &[EncoderLayers<'_>],
    grids: &Grids,
    sparse_below: Option<f32>,
) -> Option<Tensor<2>> {
    let k = bodies.len();
    let n = grids.len();
    let hidden = bodies.first()?.fc.weight.dims()[1];
    let dev = bodies[0].fc.weight.val().device();
    // The grid input: the dense tensor, or an untracked placeholder for compact grids.
    let grid_tensor: Tensor<1> = match grids {
        Grids::Dense(t) => t.clone().flatten(0, 3),
        Grids::Compact(_) => Tensor::zeros([1], &dev),
    };
    let mut inputs = vec![grid_tensor];
    for l in bodies {
        inputs.extend(encoder_params(l.conv1, l.conv2, l.fc)?);
    }
    let (prims, tracked) = prims(inputs)?;
    let vals: Vec<Cow<'_, [f32]>> = prims.iter().map(|p| values(p.flex())).collect();
    let mut w1 = Vec::with_capacity(C1 * k * PATCH1);
    let mut b1 = Vec::with_capacity(C1 * k);
    let (mut w2, mut b2, mut wfc, mut bfc) = (vec![], vec![], vec![], vec![]);
    for b in 0..k {
        let v = |i: usize| vals[1 + 6 * b + i].to_vec();
        w1.extend_from_slice(&vals[1 + 6 * b]);
        b1.extend_from_slice(&vals[2 + 6 * b]);
        w2.push(v(2));
        b2.push(v(3));
        wfc.push(v(4));
        bfc.push(v(5));
    }
    let mut pack = EncoderPack::new(k, hidden, bodies[0].slope, w1, b1, w2, b2, wfc, bfc);
    if let Some(below) = sparse_below {
        pack.sparse_below = below;
        pack.sparse_below_acting = below;
        pack.sparse_below_dense = below;
    }
    let grid_data = match grids {
        Grids::Dense(_) => GridsData::Dense(contiguous(prims[0].flex())),
        Grids::Compact(c) => GridsData::Compact(c.clone()),
    };
    drop(vals);
    let mut saved = pack.forward(grid_data.as_ref());
    let out = flex(std::mem::take(&mut saved.h), &[n, k * hidden]);
    if !tracked {
        return Some(Tensor::from_primitive::<Flex>(out));
    }
    saved.h = values(&out).into_owned();
    let state = EncoderState {
        pack: Arc::new(pack),
        grids: grid_data,
        saved: Arc::new(saved),
    };
    let guards = graph_nodes(&prims);
    macro_rules! finish {
        ($n:literal) => {{
            let guards: [_; $n] = guards.try_into().expect("1 + 6·K inputs");
            match EncoderBackward::<$n>
                .prepare::<NoCheckpointing>(guards)
                .compute_bound()
                .stateful()
            {
                OpsKind::Tracked(prep) => prep.finish(state, out),
                OpsKind::UnTracked(prep) => prep.finish(out),
            }
        }};
    }
    let ad = match k {
        1 => finish!(7),
        2 => finish!(13),
        3 => finish!(19),
        _ => return None,
    };
    Some(Tensor::from_primitive::<Ad>(ad))
}

#[derive(Clone, Debug)]
struct DenseState {
    pack: Arc<DensePack>,
    x: FlexTensor,
    z: Arc<Vec<f32>>,
}

#[derive(Debug)]
struct DenseBackward;

impl Backward<Flex, 3> for DenseBackward {
    type State = DenseState;

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, _: &mut Checkpointer) {
        let st = ops.state;
        let dy = grads.consume::<Flex>(&ops.node);
        let dy = values(&dy);
        let x = values(&st.x);
        let input_grad = ops.parents[0].is_some();
        let (g, dx) = st.pack.backward_silu(&x, &st.z, &dy, input_grad);
        let n = x.len() / st.pack.d_in;
        let [px, pw, pb] = &ops.parents;
        // Every input entered flattened (1-D): gradients are registered so.
        if let (Some(node), Some(dx)) = (px, dx) {
            grads.register::<Flex>(node.id, flex(dx, &[n * st.pack.d_in]));
        }
        if let Some(node) = pw {
            grads.register::<Flex>(node.id, flex(g.w, &[st.pack.d_in * st.pack.d_out]));
        }
        if let Some(node) = pb {
            grads.register::<Flex>(node.id, flex(g.b, &[st.pack.d_out]));
        }
    }
}

/// `silu(x·W + b)` for a Burn `Linear` (with bias) on `x` `[n, d_in]`. `None`
/// unless every tensor is on the Flex backend.
pub fn dense_silu(x: Tensor<2>, layer: &Linear) -> Option<Tensor<2>> {
    let [n, d_in] = x.dims();
    let [_, d_out] = layer.weight.dims();
    let inputs = vec![
        x.flatten::<1>(0, 1),
        layer.weight.val().flatten::<1>(0, 1),
        layer.bias.as_ref()?.val(),
    ];
    let (prims, tracked) = prims(inputs)?;
    let pack = DensePack {
        d_in,
        d_out,
        w: values(prims[1].flex()).into_owned(),
        b: values(prims[2].flex()).into_owned(),
    };
    let xv = values(prims[0].flex());
    let (y, z) = pack.forward_silu(&xv);
    drop(xv);
    let out = flex(y, &[n, d_out]);
    if !tracked {
        return Some(Tensor::from_primitive::<Flex>(out));
    }
    let state = DenseState {
        pack: Arc::new(pack),
        x: contiguous(prims[0].flex()),
        z: Arc::new(z),
    };
    Some(track(DenseBackward, &prims, state, out))
}

/// `out`, computed from the three tracked inputs `prims`, as an autodiff
/// tensor whose backward step is `op` with `state`.
fn track<const D: usize, B: Backward<Flex, 3>>(
    op: B,
    prims: &[Prim],
    state: B::State,
    out: FlexTensor,
) -> Tensor<D> {
    let guards: [_; 3] = graph_nodes(prims).try_into().expect("three inputs");
    let ad = match op
        .prepare::<NoCheckpointing>(guards)
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(prep) => prep.finish(state, out),
        OpsKind::UnTracked(prep) => prep.finish(out),
    };
    Tensor::from_primitive::<Ad>(ad)
}

#[derive(Clone, Debug)]
struct ConvState {
    pack: Arc<ConvPack>,
    x: FlexTensor,
    y: FlexTensor,
    n: usize,
    hw: (usize, usize),
}

#[derive(Debug)]
struct ConvBackward;

impl Backward<Flex, 3> for ConvBackward {
    type State = ConvState;

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, _: &mut Checkpointer) {
        let st = ops.state;
        let dy = grads.consume::<Flex>(&ops.node);
        let dy = values(&dy);
        let (x, y) = (values(&st.x), values(&st.y));
        let input_grad = ops.parents[0].is_some();
        let (g, dx) = st.pack.backward(&x, &y, &dy, st.n, st.hw, input_grad);
        let [px, pw, pb] = &ops.parents;
        // Every input entered flattened (1-D): gradients are registered so.
        if let (Some(node), Some(dx)) = (px, dx) {
            let len = dx.len();
            grads.register::<Flex>(node.id, flex(dx, &[len]));
        }
        if let Some(node) = pw {
            let len = g.w.len();
            grads.register::<Flex>(node.id, flex(g.w, &[len]));
        }
        if let Some(node) = pb {
            let len = g.b.len();
            grads.register::<Flex>(node.id, flex(g.b, &[len]));
        }
    }
}

/// A Burn `Conv2d` (with bias) on `x` `[n, c_in, h, w]`, then LeakyReLU of
/// negative slope `slope` (none for `None`), by [`ConvPack`]'s im2col + GEMM
/// with a hand-written backward. `None` (use Burn's layer) unless every
/// tensor is on the Flex backend and the layer is one the kernel covers: one
/// group, a square kernel, the same stride and dilation on both axes and
/// symmetric padding.
pub fn conv2d(x: Tensor<4>, conv: &Conv2d, slope: Option<f32>) -> Option<Tensor<4>> {
    let [n, c_in, h, w] = x.dims();
    let [c_out, w_in, k, k2] = conv.weight.dims();
    let padding = match conv.padding {
        PaddingConfig2d::Valid => 0,
        PaddingConfig2d::Explicit(t, l, b, r) if t == l && t == b && t == r => t,
        _ => return None,
    };
    let square = |[a, b]: [usize; 2]| (a == b).then_some(a);
    if conv.groups != 1 || w_in != c_in || k != k2 {
        return None;
    }
    let mut pack = ConvPack {
        c_in,
        c_out,
        k,
        stride: square(conv.stride)?,
        dilation: square(conv.dilation)?,
        padding,
        w: vec![],
        b: vec![],
        slope,
    };
    let (ho, wo) = pack.out_size(h, w)?;
    let inputs = vec![
        x.flatten::<1>(0, 3),
        conv.weight.val().flatten::<1>(0, 3),
        conv.bias.as_ref()?.val(),
    ];
    let (prims, tracked) = prims(inputs)?;
    pack.w = values(prims[1].flex()).into_owned();
    pack.b = values(prims[2].flex()).into_owned();
    let xv = values(prims[0].flex());
    let y = pack.forward(&xv, n, (h, w));
    drop(xv);
    let out = flex(y, &[n, c_out, ho, wo]);
    if !tracked {
        return Some(Tensor::from_primitive::<Flex>(out));
    }
    let state = ConvState {
        pack: Arc::new(pack),
        x: contiguous(prims[0].flex()),
        y: out.clone(),
        n,
        hw: (h, w),
    };
    Some(track(ConvBackward, &prims, state, out))
}
