//! One-step integrators for ẋ = g(x, u) with u held constant over Δt (paper appendix B).

use serde::{Deserialize, Serialize};

use super::scalar::Scalar;
use super::space::Space;
use crate::arena::AVec;

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

    /// x_{t+Δt} from x_t for a batch of `states` (rows [q, v]), given the vector field `g`
    /// (the input is captured by `g`), which returns each row's tangent [v, v̇]. Each stage's
    /// configuration is integrate(q, c·Δt·k) and so is the step's, RK4 on the manifold
    /// (docs/dynamics.md#configuration-space); for a flat space that is x + c·Δt·k.
    pub fn step<V: StateVec>(self, states: &States, x: &V, dt: f64, g: impl Fn(&V) -> V) -> V {
        match self {
            Integrator::Euler => states.advance(x, dt, &g(x)),
            Integrator::Midpoint => {
                let k1 = g(x);
                states.advance(x, dt, &g(&states.advance(x, 0.5 * dt, &k1)))
            }
            Integrator::Rk4 => {
                let k1 = g(x);
                let k2 = g(&states.advance(x, 0.5 * dt, &k1));
                let k3 = g(&states.advance(x, 0.5 * dt, &k2));
                let k4 = g(&states.advance(x, dt, &k3));
                // x ⊕ Δt/6 (k1 + 2k2 + 2k3 + k4)
                let sum = k1.axpy(2.0, &k2).axpy(2.0, &k3).axpy(1.0, &k4);
                states.advance(x, dt / 6.0, &sum)
            }
        }
    }
}

/// A batch of `rows` states [q, v] in a configuration space.
#[derive(Debug, Clone, Copy)]
pub struct States<'s> {
    pub space: &'s Space,
    pub rows: usize,
}

impl<'s> States<'s> {
    pub fn new(space: &'s Space, rows: usize) -> Self {
        Self { space, rows }
    }

    /// x ⊕ a·k: each row's [integrate(q, a·k_v), v + a·k_v̇] for tangents k = [k_v, k_v̇].
    pub fn advance<V: StateVec>(&self, x: &V, a: f64, k: &V) -> V {
        if self.space.is_flat() {
            // x + a·k, as every flat model's answers were recorded.
            return x.axpy(a, k);
        }
        x.advance(self, a, k)
    }
}

/// What an integrator needs of a state: self + a·x, and a batch of states moved along their
/// tangents.
pub trait StateVec: Sized {
    fn axpy(&self, a: f64, x: &Self) -> Self;
    /// [`States::advance`] for a space that is not flat.
    fn advance(&self, states: &States, a: f64, k: &Self) -> Self;
}

/// Rows [q, v] of `x` moved along rows [k_v, k_v̇] of `k`, appended to `out`.
fn advance_rows<S: Scalar>(states: &States, x: &[S], a: f64, k: &[S], out: &mut impl Extend<S>) {
    let (space, nv) = (states.space, states.space.nv());
    let nq = space.nq();
    for (x, k) in x.chunks(nq + nv).zip(k.chunks(2 * nv)) {
        space.integrate_into(&x[..nq], a, &k[..nv], out);
        out.extend(
            x[nq..]
                .iter()
                .zip(&k[nv..])
                .map(|(v, d)| v.clone() + d.scale(a)),
        );
    }
}

impl<S: Scalar> StateVec for AVec<'_, S> {
    fn axpy(&self, a: f64, x: &Self) -> Self {
        let out = self.iter().zip(x).map(|(s, x)| s.clone() + x.scale(a));
        AVec::from_iter_in(out, self.bump())
    }
    fn advance(&self, states: &States, a: f64, k: &Self) -> Self {
        let mut out = AVec::with_capacity_in(self.len(), self.bump());
        advance_rows(states, self, a, k, &mut out);
        out
    }
}

impl<S: Scalar> StateVec for Vec<S> {
    fn axpy(&self, a: f64, x: &Self) -> Self {
        self.iter()
            .zip(x)
            .map(|(s, x)| s.clone() + x.scale(a))
            .collect()
    }
    fn advance(&self, states: &States, a: f64, k: &Self) -> Self {
        let mut out = Vec::with_capacity(self.len());
        advance_rows(states, self, a, k, &mut out);
        out
    }
}
