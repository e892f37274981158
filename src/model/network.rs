//! A network's trainable weights: tanh hidden layers and a linear output, computed by the
//! fused step's network node (`physics::tape::mlp`, with its input derivatives in forward
//! mode: docs/dynamics.md#forward-mode-input-derivatives); Burn holds them for Adam and
//! checkpoints.
//!
//! Weights are stored `[in, out]` (Burn's `Linear` layout) and biases `[1, out]`, so every
//! parameter is rank 2 and the optimizer and checkpoint code handle one tensor kind; their
//! names in a model file are `layers.{i}.weight` and `layers.{i}.bias` under the network's.

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
}

/// A trainable rank-2 parameter from f64 values (converted to the device's float dtype).
pub fn param(values: Vec<f64>, shape: [usize; 2], device: &Device) -> Param<Tensor<2>> {
    Param::from_tensor(Tensor::from_data(TensorData::new(values, shape), device))
}

#[derive(Module, Debug)]
pub struct Network {
    pub layers: Vec<Dense>,
}

impl Network {
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
        let last = net
            .layers
            .last_mut()
            .expect("a network has an output layer");
        let d_last = last.weight.val().dims()[0];
        *last = Dense {
            weight: param(vec![0.0; d_last * d_out], [d_last, d_out], device),
            bias: param(vec![0.0; d_out], [1, d_out], device),
        };
        net
    }
}
