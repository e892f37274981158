//! The loss's constant tensors, built once per device: each state entry's weight
//! [1…1, λ…λ] and, when some coordinate is an angle, where its wrapped error replaces Δ².
//! A rotation kept as a unit complex number needs no mask: the squared errors of its two
//! values sum to |z′ − z|² = 2(1 − cos Δθ), the angle's own distance
//! (docs/dynamics.md#configuration-space).

use burn::tensor::{Device, Tensor, TensorData};

use super::ModelConfig;
use crate::physics::space::Joint;

#[derive(Debug, Clone)]
pub(super) struct Loss {
    /// `[1, nq + nv]`: 1 for configuration values, λ for velocities.
    weights: Tensor<2>,
    /// `[1, nq + nv]` each: 1 at the angles' entries (`wrap`), 1 elsewhere (`keep`).
    periodic: Option<(Tensor<2>, Tensor<2>)>,
}

fn row(values: Vec<f64>, device: &Device) -> Tensor<2> {
    let k = values.len();
    Tensor::from_data(TensorData::new(values, [1, k]), device)
}

impl Loss {
    pub(super) fn new(c: &ModelConfig, device: &Device) -> Self {
        let (nq, nv) = (c.nq(), c.nv());
        let mut angles = vec![false; nq + nv];
        for p in c.space.placed().filter(|p| p.joint == Joint::Angle) {
            angles[p.q.start] = true;
        }
        let mask = |angle: bool| angles.iter().map(move |&a| f64::from(a == angle));
        Self {
            weights: row([vec![1.0; nq], vec![c.lambda; nv]].concat(), device),
            periodic: angles.contains(&true).then(|| {
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

    /// Σ over a batch of the weighted per-entry loss of state errors `[batch, nq + nv]`.
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
