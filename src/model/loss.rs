//! The loss's constant tensors, built once per device: each state entry's weight
//! [1…1, λ…λ] and, when some coordinate is an angle, where its wrapped error replaces Δ².

use burn::tensor::{Device, Tensor, TensorData};

use super::ModelConfig;

#[derive(Debug, Clone)]
pub(super) struct Loss {
    /// `[1, 2n]`: 1 for positions, λ for velocities.
    weights: Tensor<2>,
    /// `[1, 2n]` each: 1 at the angles' position entries (`wrap`), 1 elsewhere (`keep`).
    periodic: Option<(Tensor<2>, Tensor<2>)>,
}

fn row(values: Vec<f64>, device: &Device) -> Tensor<2> {
    let k = values.len();
    Tensor::from_data(TensorData::new(values, [1, k]), device)
}

impl Loss {
    pub(super) fn new(c: &ModelConfig, device: &Device) -> Self {
        let n = c.n;
        let mask = |angle: bool| (0..2 * n).map(move |k| f64::from(c.is_periodic(k) == angle));
        Self {
            weights: row([vec![1.0; n], vec![c.lambda; n]].concat(), device),
            periodic: (!c.periodic.is_empty()).then(|| {
                (
                    row(mask(true).collect(), device),
                    row(mask(false).collect(), device),
                )
            }),
        }
    }

    pub(super) fn device(&self) -> Device {
        self.weights.device()
    }

    /// Σ over a batch of the weighted per-entry loss of state errors `[batch, 2n]`.
    pub(super) fn sum(&self, err: Tensor<2>) -> Tensor<1> {
        (self.squared_error(err) * self.weights.clone()).sum()
    }

    /// Δ², or 2(1 − cos Δ) for an angle (Δ² near zero, blind to whole turns).
    fn squared_error(&self, err: Tensor<2>) -> Tensor<2> {
        match &self.periodic {
            None => err.square(),
            Some((wrap, keep)) => {
                let wrapped = err.clone().cos().neg().add_scalar(1.0).mul_scalar(2.0);
                err.square() * keep.clone() + wrapped * wrap.clone()
            }
        }
    }
}
