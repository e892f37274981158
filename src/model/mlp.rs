//! Multi-layer perceptron with tanh hidden layers and a linear output, plus its input
//! Jacobian in forward mode (docs/dynamics.md#forward-mode-input-derivatives).
//!
//! Weights are stored `[in, out]` (Burn's `Linear` layout) and biases `[1, out]`, so every
//! parameter is rank 2 and the optimizer and checkpoint code handle one tensor kind.

use burn::module::{Module, Param};
use burn::tensor::{Device, Tensor, TensorData};

use crate::rng::Rng;

#[derive(Module, Debug)]
pub struct Dense {
    pub weight: Param<Tensor<2>>, // [in, out]
    pub bias: Param<Tensor<2>>,   // [1, out]
}

impl Dense {
    /// PyTorch's default initialization, U(−1/√fan_in, 1/√fan_in) for weights and biases, drawn
    /// from our own RNG so that a seed means the same network on every backend.
    pub fn init(d_in: usize, d_out: usize, rng: &mut Rng, device: &Device) -> Self {
        let bound = 1.0 / (d_in as f64).sqrt();
        let mut draw = |count: usize| -> Vec<f64> {
            (0..count).map(|_| rng.uniform_in(-bound, bound)).collect()
        };
        let w = draw(d_in * d_out);
        let b = draw(d_out);
        Self {
            weight: param(w, [d_in, d_out], device),
            bias: param(b, [1, d_out], device),
        }
    }

    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        x.matmul(self.weight.val()) + self.bias.val()
    }
}

/// A trainable rank-2 parameter from f64 values (converted to the device's float dtype).
pub fn param(values: Vec<f64>, shape: [usize; 2], device: &Device) -> Param<Tensor<2>> {
    Param::from_tensor(Tensor::from_data(TensorData::new(values, shape), device))
}

#[derive(Module, Debug)]
pub struct Mlp {
    pub layers: Vec<Dense>,
}

impl Mlp {
    pub fn init(
        d_in: usize,
        hidden: &[usize],
        d_out: usize,
        rng: &mut Rng,
        device: &Device,
    ) -> Self {
        let mut sizes = vec![d_in];
        sizes.extend_from_slice(hidden);
        sizes.push(d_out);
        let layers = sizes
            .windows(2)
            .map(|w| Dense::init(w[0], w[1], rng, device))
            .collect();
        Self { layers }
    }

    /// A network whose output starts at zero (its last layer zero; the hidden layers drawn as
    /// usual, so that gradients reach them once the last layer moves): a residual added to a
    /// physics part leaves the model exactly that part at the start of training.
    pub fn init_zero_output(
        d_in: usize,
        hidden: &[usize],
        d_out: usize,
        rng: &mut Rng,
        device: &Device,
    ) -> Self {
        let mut net = Self::init(d_in, hidden, d_out, rng, device);
        let last = net.layers.last_mut().expect("an MLP has an output layer");
        let d_last = last.weight.val().dims()[0];
        *last = Dense {
            weight: param(vec![0.0; d_last * d_out], [d_last, d_out], device),
            bias: param(vec![0.0; d_out], [1, d_out], device),
        };
        net
    }

    pub fn d_out(&self) -> usize {
        self.layers.last().map_or(0, |l| l.weight.val().dims()[1])
    }

    /// y = W_L tanh(… tanh(W_1 x + b_1) …) + b_L.  x: [batch, in] → [batch, out].
    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        let (last, hidden) = self
            .layers
            .split_last()
            .expect("an MLP has an output layer");
        let h = hidden.iter().fold(x, |h, layer| tanh(layer.forward(h)));
        last.forward(h)
    }

    /// The output and its Jacobian with respect to the variables q that the input depends on
    /// linearly through `dx_dq` (`[n, in]`, constant across the batch, e.g. diag(1/σ_q)).
    ///
    /// Forward mode: J₁ = (∂x/∂q · W₁) ⊙ (1 − h₁²),  J_l = (J_{l−1} W_l) ⊙ (1 − h_l²),
    /// ∂y/∂q = J_L W_out.  Returns y `[batch, out]` and J `[batch, n, out]`.
    pub fn forward_jacobian(
        &self,
        x: Tensor<2>,
        dx_dq: impl Into<InputTangent>,
    ) -> (Tensor<2>, Tensor<3>) {
        let (y, j) = self.propagate(x, dx_dq.into(), true);
        (y.expect("asked for the output"), j)
    }

    /// Only the Jacobian `[batch, n, out]` (a potential needs ∂V/∂q, not V). Not computing
    /// the unused output matters: a tracked result that never reaches the loss stays in
    /// Burn's autodiff graph registry and slows every later backward pass.
    pub fn jacobian(&self, x: Tensor<2>, dx_dq: impl Into<InputTangent>) -> Tensor<3> {
        self.propagate(x, dx_dq.into(), false).1
    }

    fn propagate(
        &self,
        x: Tensor<2>,
        dx_dq: InputTangent,
        want_y: bool,
    ) -> (Option<Tensor<2>>, Tensor<3>) {
        let (last, hidden) = self
            .layers
            .split_last()
            .expect("an MLP has an output layer");
        let [batch, _] = x.dims();
        let (n, mut jac, mut dz_dq_const) = match dx_dq {
            // The first layer's Jacobian is batch-independent: one small product.
            InputTangent::Constant(d) => (d.dims()[0], None, Some(d)),
            InputTangent::PerSample(d) => (d.dims()[1], Some(d), None),
        };
        let mut h = x;
        for layer in hidden {
            h = tanh(layer.forward(h));
            let dh = h
                .clone()
                .square()
                .neg()
                .add_scalar(1.0)
                .unsqueeze_dim::<3>(1); // [batch, 1, w]
            jac = Some(match (jac, dz_dq_const.take()) {
                (None, Some(dx)) => dx.matmul(layer.weight.val()).unsqueeze_dim::<3>(0) * dh,
                (Some(j), _) => mat3(j, layer.weight.val()) * dh,
                (None, None) => unreachable!("the Jacobian starts at the first layer"),
            });
        }
        let y = want_y.then(|| last.forward(h));
        let j = match (jac, dz_dq_const) {
            (Some(j), _) => mat3(j, last.weight.val()),
            // No hidden layers: the net is affine in x.
            (None, Some(dx)) => dx
                .matmul(last.weight.val())
                .unsqueeze_dim::<3>(0)
                .repeat_dim(0, batch),
            (None, None) => unreachable!(),
        };
        debug_assert_eq!(j.dims()[1], n);
        (y, j)
    }
}

/// ∂x/∂q of a network's input x: `[n, in]` when x is affine in q (standardized q), or
/// `[batch, n, in]` when it is not (the (sin q, cos q) of periodic coordinates).
pub enum InputTangent {
    Constant(Tensor<2>),
    PerSample(Tensor<3>),
}

impl From<Tensor<2>> for InputTangent {
    fn from(t: Tensor<2>) -> Self {
        InputTangent::Constant(t)
    }
}

impl From<Tensor<3>> for InputTangent {
    fn from(t: Tensor<3>) -> Self {
        InputTangent::PerSample(t)
    }
}

/// The hidden layers' activation: one fused Burn op (the core's `tensor_scalar/tanh.rs`).
pub fn tanh<const D: usize>(z: Tensor<D>) -> Tensor<D> {
    crate::backend::tanh(z)
}

/// [batch, n, a] · [a, b] → [batch, n, b]
fn mat3(j: Tensor<3>, w: Tensor<2>) -> Tensor<3> {
    let [batch, n, a] = j.dims();
    let b = w.dims()[1];
    j.reshape([batch * n, a]).matmul(w).reshape([batch, n, b])
}
