//! One-step integrators for ẋ = g(x, u) with u held constant over Δt (paper appendix B).

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// Classic fourth-order Runge–Kutta (the paper's appendix B).
    #[default]
    Rk4,
    /// Explicit (forward) Euler, first order.
    Euler,
    /// Explicit midpoint, second order.
    Midpoint,
}

impl Integrator {
    pub const ALL: [Integrator; 3] = [Integrator::Rk4, Integrator::Euler, Integrator::Midpoint];

    pub fn name(self) -> &'static str {
        match self {
            Integrator::Rk4 => "rk4",
            Integrator::Euler => "euler",
            Integrator::Midpoint => "midpoint",
        }
    }

    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|i| i.name() == s)
    }

    /// A name given by a person (the `integrator` field or flag); an unknown one is an error
    /// listing the known.
    pub fn parse(s: &str) -> crate::error::Result<Self> {
        Self::from_name(s).ok_or_else(|| {
            crate::error::Error::invalid(
                "integrator",
                format!("unknown integrator '{s}'; expected rk4, euler or midpoint"),
            )
        })
    }

    /// x_{t+Δt} from x_t, given the vector field `g` (the input is captured by `g`).
    pub fn step<V: StateVec>(self, x: &V, dt: f64, g: impl Fn(&V) -> V) -> V {
        match self {
            Integrator::Euler => x.axpy(dt, &g(x)),
            Integrator::Midpoint => {
                let k1 = g(x);
                x.axpy(dt, &g(&x.axpy(0.5 * dt, &k1)))
            }
            Integrator::Rk4 => {
                let k1 = g(x);
                let k2 = g(&x.axpy(0.5 * dt, &k1));
                let k3 = g(&x.axpy(0.5 * dt, &k2));
                let k4 = g(&x.axpy(dt, &k3));
                // x + Δt/6 (k1 + 2k2 + 2k3 + k4)
                let sum = k1.axpy(2.0, &k2).axpy(2.0, &k3).axpy(1.0, &k4);
                x.axpy(dt / 6.0, &sum)
            }
        }
    }
}

/// What an integrator needs of a state: self + a·x.
pub trait StateVec: Sized {
    fn axpy(&self, a: f64, x: &Self) -> Self;
}

impl<S: super::scalar::Scalar> StateVec for crate::arena::AVec<'_, S> {
    fn axpy(&self, a: f64, x: &Self) -> Self {
        let out = self.iter().zip(x).map(|(s, x)| s.clone() + x.scale(a));
        crate::arena::AVec::from_iter_in(out, self.bump())
    }
}

impl<S: super::scalar::Scalar> StateVec for Vec<S> {
    fn axpy(&self, a: f64, x: &Self) -> Self {
        self.iter()
            .zip(x)
            .map(|(s, x)| s.clone() + x.scale(a))
            .collect()
    }
}
