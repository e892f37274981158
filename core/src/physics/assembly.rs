//! A structured model assembled from its spec, once, for every number type: L(q) with its
//! q-derivatives, ∇V and F, the terms of the manipulator equation M q̈ = F − c − ∇V
//! (docs/dynamics.md#manipulator-equation). Training records it on the tape, inference on f64, batch columns
//! and dual numbers; only the networks' evaluation differs, behind [`Networks`], and the
//! trainable non-network values, behind [`Coef`] (the tape's values in training, constants in
//! inference). A new component kind is one arm here.

use std::ops::Range;

use super::dual::{Dual, groups};
use super::dynamics::{Factor, cholesky, tri_index};
use super::mass_matrix::{factor_from_outputs, outputs};
use super::scalar::Scalar;
use super::space::Space;
use super::templates::Template;
use crate::arena::{AVec, Arena, CollectIn};
use crate::physics::parts::{ForceSpec, MassSpec, PotentialSpec};
use crate::physics::scaling::Scaling;

/// The floor ε of a passive force's damping D = S(L Lᵀ + εI)S, in the data's scaled units:
/// D is positive definite even where the network's factor is singular, and 1e-3 of the
/// scaled force per scaled velocity is far below any damping worth learning.
pub const PASSIVE_EPS: f64 = 1e-3;

/// The networks' outputs for a batch, read by index; each is asked for only when the spec
/// has that network.
pub trait Networks<S: Scalar> {
    /// Output j of the mass network (the raw entries of L) with its q-tangents in the
    /// directions `dirs`.
    fn mass(&self, j: usize, dirs: Range<usize>) -> Dual<S>;
    /// ∂V/∂q_k of the potential network's (unscaled) output.
    fn potential_grad(&self, k: usize) -> S;
    /// Output j of the force network (general F, unscaled) or of the B network (B_θ(q)).
    fn force(&self, j: usize) -> S;
    /// Output j of a passive force's damping network: the raw entries of D's factor.
    fn damping(&self, j: usize) -> S;
}

/// The batch's inputs as columns, built when first read: in training, a tracked value that
/// never reaches the loss keeps its autodiff graph alive (see `Model::parts`).
pub trait Inputs<S> {
    fn q(&self) -> &[S];
    fn qd(&self) -> &[S];
    fn u(&self) -> &[S];
    /// The unit tangent seeding q's dual variables.
    fn one(&self) -> S;
}

/// A batch's inputs, already columns (the f64 evaluator's, the fused step's).
pub struct Columns<'a, S> {
    pub q: &'a [S],
    pub qd: &'a [S],
    pub u: &'a [S],
}

impl<S: Scalar> Inputs<S> for Columns<'_, S> {
    fn q(&self) -> &[S] {
        self.q
    }
    fn qd(&self) -> &[S] {
        self.qd
    }
    fn u(&self) -> &[S] {
        self.u
    }
    fn one(&self) -> S {
        self.q[0].lift(1.0)
    }
}

/// A trainable value that is not a network output: a constant in inference, a tracked
/// tensor in training.
pub trait Coef<S>: Clone {
    /// x · self.
    fn times(&self, x: &S) -> S;
    /// self as a value of the batch's kind, shaped like `like`.
    fn value(&self, like: &S) -> S;
    /// self · mul / div.
    fn mul_div(&self, mul: f64, div: f64) -> Self;
}

impl<S: Scalar> Coef<S> for f64 {
    fn times(&self, x: &S) -> S {
        x.scale(*self)
    }
    fn value(&self, like: &S) -> S {
        like.lift(*self)
    }
    fn mul_div(&self, mul: f64, div: f64) -> Self {
        self * mul / div
    }
}

/// The non-network values of a structured model, each present when the spec uses it.
pub struct Values<'a, P> {
    /// Raw entries of a constant L.
    pub mass_const: Option<&'a [P]>,
    /// K of ½qᵀKq, row-major lower triangle.
    pub potential_quad: Option<&'a [P]>,
    /// Constant B, `n·m` row-major.
    pub b_const: Option<&'a [P]>,
    /// Damping η.
    pub eta: Option<&'a [P]>,
    /// The template's physical values (positive ones exponentiated).
    pub physical: Option<&'a [P]>,
}

/// The terms of M q̈ = F − c − ∂V/∂q for a batch.
pub struct Terms<'a, S> {
    /// L(q) with ∂L/∂q_k.
    pub factor: Factor<'a, S>,
    /// ∂V/∂q (`None` for a zero potential).
    pub grad_v: Option<AVec<'a, S>>,
    pub forces: AVec<'a, S>,
}

/// A structured model's parts and what they read.
pub struct Structure<'a, P> {
    pub mass: &'a MassSpec,
    pub potential: &'a PotentialSpec,
    pub forces: &'a ForceSpec,
    pub template: Option<&'a Template>,
    pub scaling: &'a Scaling,
    pub values: Values<'a, P>,
    /// The configuration space: q's nq values, and nv of everything else.
    pub space: &'a Space,
    pub m: usize,
    /// Where its vectors are made.
    pub arena: &'a Arena,
}

impl<'a, P> Structure<'a, P> {
    /// L, ∇V and F for a batch.
    pub fn terms<S: Scalar>(&self, nets: &impl Networks<S>, x: &impl Inputs<S>) -> Terms<'a, S>
    where
        P: Coef<S>,
    {
        Terms {
            factor: self.mass_factor(nets, x),
            grad_v: self.potential_grad(nets, x),
            forces: self.generalized_forces(nets, x),
        }
    }

    /// The tangent's width nv: M is nv × nv, ∇V and F nv wide.
    pub fn n(&self) -> usize {
        self.space.nv()
    }

    pub(super) fn template(&self) -> &'a Template {
        self.template
            .expect("validated: white-box parts have a template")
    }

    pub(super) fn physical<S: Scalar>(&self, like: &S) -> AVec<'a, S>
    where
        P: Coef<S>,
    {
        (self.physical_values().iter().map(|v| v.value(like))).collect_in(self.arena)
    }

    fn physical_values(&self) -> &'a [P] {
        (self.values.physical).expect("a template model has physical values")
    }

    fn physical_dual<S: Scalar>(&self, like: &S) -> AVec<'a, Dual<S>>
    where
        P: Coef<S>,
    {
        let p = self.physical_values().iter();
        p.map(|v| Dual::constant(v.value(like)))
            .collect_in(self.arena)
    }

    /// q as dual numbers in the tangent directions `dirs` (q ⊕ ε e_k), for the analytic parts
    /// that need ∂/∂q.
    fn q_vars<S: Scalar>(&self, x: &impl Inputs<S>, dirs: Range<usize>) -> AVec<'a, Dual<S>> {
        self.space.seeded_in(self.arena, x.q(), &x.one(), dirs)
    }

    /// L(q) = the Cholesky factor of M(q), with its q-tangents.
    fn mass_factor<S: Scalar>(&self, nets: &impl Networks<S>, x: &impl Inputs<S>) -> Factor<'a, S>
    where
        P: Coef<S>,
    {
        let n = self.n();
        let a = self.arena;
        Factor::from_groups(a, n, |dirs| match self.mass {
            MassSpec::Mlp { .. } => {
                factor_from_outputs(a, (0..outputs(n)).map(|j| nets.mass(j, dirs.clone())), n)
            }
            MassSpec::Constant => {
                let raw = self.values.mass_const.expect("constant mass");
                let like = &x.q()[0];
                factor_from_outputs(a, raw.iter().map(|v| Dual::constant(v.value(like))), n)
            }
            MassSpec::Template => {
                let p = self.physical_dual(&x.q()[0]);
                cholesky(a, &self.template().mass_in(a, &p, &self.q_vars(x, dirs)))
            }
        })
    }

    /// ∂V/∂q.
    fn potential_grad<S: Scalar>(
        &self,
        nets: &impl Networks<S>,
        x: &impl Inputs<S>,
    ) -> Option<AVec<'a, S>>
    where
        P: Coef<S>,
    {
        let (n, s, a) = (self.n(), self.scaling, self.arena);
        let network = || self.potential_network_grad(nets);
        match self.potential {
            PotentialSpec::Zero => None,
            PotentialSpec::Mlp { .. } => Some(network()),
            PotentialSpec::Quadratic => {
                let k = self.values.potential_quad.expect("quadratic potential");
                let kij = |i: usize, j: usize| &k[tri_index(i.max(j), i.min(j))];
                let q = x.q();
                Some(
                    (0..n)
                        .map(|i| {
                            (0..n)
                                .map(|j| kij(i, j).times(&q[j]))
                                .reduce(|a, b| a + b)
                                .expect("n ≥ 1")
                                .scale(s.quadratic_scale())
                        })
                        .collect_in(a),
                )
            }
            PotentialSpec::Template { residual } => {
                let p = self.physical_dual(&x.q()[0]);
                let zero = || x.q()[0].lift(0.0);
                let grad = groups::<S>(n).flat_map(|dirs| {
                    let v = (self.template()).potential_in(
                        self.arena,
                        &p,
                        &self.q_vars(x, dirs.clone()),
                    );
                    (0..dirs.len()).map(move |k| v.tangent(k).cloned().unwrap_or_else(zero))
                });
                Some(match residual {
                    None => grad.collect_in(a),
                    Some(_) => grad.zip(network()).map(|(t, r)| t + r).collect_in(a),
                })
            }
        }
    }

    /// ∂V/∂q of the potential's network (in the data's units).
    fn potential_network_grad<S: Scalar>(&self, nets: &impl Networks<S>) -> AVec<'a, S> {
        let scale = self.scaling.potential_scale();
        (0..self.n())
            .map(|k| nets.potential_grad(k).scale(scale))
            .collect_in(self.arena)
    }

    /// τ = F − ∂V′/∂q: what a rigid-body algorithm that supplies M, the Coriolis term and
    /// gravity itself (the template's V) takes as joint forces; V′ is the rest of V (a
    /// template's residual network, or a whole potential that is not the template's, whose
    /// algorithm then runs without gravity: `gravity_in_template`).
    pub fn multibody_torques<S: Scalar>(
        &self,
        nets: &impl Networks<S>,
        x: &impl Inputs<S>,
    ) -> AVec<'a, S>
    where
        P: Coef<S>,
    {
        let mut f = self.generalized_forces(nets, x);
        let rest = match self.potential {
            PotentialSpec::Template { residual: None } => None,
            PotentialSpec::Template { residual: Some(_) } => {
                Some(self.potential_network_grad(nets))
            }
            _ => self.potential_grad(nets, x),
        };
        for (f, g) in f.iter_mut().zip(rest.iter().flatten()) {
            *f = f.clone() - g.clone();
        }
        f
    }

    /// F(q, q̇, u).
    fn generalized_forces<S: Scalar>(
        &self,
        nets: &impl Networks<S>,
        x: &impl Inputs<S>,
    ) -> AVec<'a, S>
    where
        P: Coef<S>,
    {
        match self.forces {
            ForceSpec::Mlp { .. } => self.force_network(nets),
            ForceSpec::ControlAffine { .. } | ForceSpec::ConstantAffine => {
                self.affine(&self.input_gain(nets, x), x)
            }
            ForceSpec::Passive { .. } => {
                let mut bu = self.input_force(&self.input_gain(nets, x), x);
                let d = self.passive_damping(nets, x);
                add_to(&mut bu, &d);
                bu
            }
            ForceSpec::Template { residual } => {
                let p = self.physical(&x.q()[0]);
                let mut f = (self.template()).forces_in(self.arena, &p, x.q(), x.qd(), x.u());
                if residual.is_some() {
                    add_to(&mut f, &self.force_network(nets));
                }
                f
            }
        }
    }

    /// The force network's output in the data's units (a general F, or a template's residual).
    pub(super) fn force_network<S: Scalar>(&self, nets: &impl Networks<S>) -> AVec<'a, S> {
        let s = self.scaling;
        (0..self.n())
            .map(|j| nets.force(j).scale(s.force_scale[j]))
            .collect_in(self.arena)
    }

    /// B(q) of a control-affine force, `n·m` row-major in the data's units.
    pub(super) fn input_gain<S: Scalar>(
        &self,
        nets: &impl Networks<S>,
        x: &impl Inputs<S>,
    ) -> AVec<'a, S>
    where
        P: Coef<S>,
    {
        let (n, m, s, a) = (self.n(), self.m, self.scaling, self.arena);
        let b_scale = |k: usize| s.force_scale[k / m] / s.u_std[k % m];
        match self.forces {
            ForceSpec::ControlAffine { .. } | ForceSpec::Passive { .. } => (0..n * m)
                .map(|k| nets.force(k).scale(b_scale(k)))
                .collect_in(a),
            ForceSpec::ConstantAffine => {
                let raw = self.values.b_const.expect("constant B");
                let like = &x.u()[0];
                raw.iter()
                    .enumerate()
                    .map(|(k, v)| v.mul_div(b_scale(k), 1.0).value(like))
                    .collect_in(a)
            }
            _ => unreachable!("only a control-affine force has an input gain"),
        }
    }

    /// B u + η ∘ q̇ in the data's units (B `n·m` row-major).
    fn affine<S: Scalar>(&self, b: &[S], x: &impl Inputs<S>) -> AVec<'a, S>
    where
        P: Coef<S>,
    {
        let (mut bu, damping) = self.affine_parts(b, x);
        add_to(&mut bu, &damping);
        bu
    }

    /// B u and η ∘ q̇, apart.
    pub(super) fn affine_parts<S: Scalar>(
        &self,
        b: &[S],
        x: &impl Inputs<S>,
    ) -> (AVec<'a, S>, AVec<'a, S>)
    where
        P: Coef<S>,
    {
        let s = self.scaling;
        let eta = self.values.eta.expect("eta");
        let qd = x.qd();
        let damping = (0..self.n()).map(|i| {
            eta[i]
                .mul_div(s.force_scale[i], s.qdot_std[i])
                .times(&qd[i])
        });
        (self.input_force(b, x), damping.collect_in(self.arena))
    }

    /// B u (B `n·m` row-major).
    pub(super) fn input_force<S: Scalar>(&self, b: &[S], x: &impl Inputs<S>) -> AVec<'a, S> {
        let (n, m, u) = (self.n(), self.m, x.u());
        (0..n)
            .map(|i| {
                (0..m)
                    .map(|j| b[i * m + j].clone() * u[j].clone())
                    .reduce(|a, b| a + b)
                    .expect("m ≥ 1")
            })
            .collect_in(self.arena)
    }

    /// −D q̇ of a passive force in the data's units: D = S (L Lᵀ + εI) S with L the damping
    /// network's factor and S = diag(√(force_scale / q̇_std)), so that q̇ᵀD q̇ = ‖Lᵀw‖² + ε‖w‖²
    /// ≥ 0 with w = S q̇ whatever the network's weights (docs/energy.md#passive-forces).
    pub(super) fn passive_damping<S: Scalar>(
        &self,
        nets: &impl Networks<S>,
        x: &impl Inputs<S>,
    ) -> AVec<'a, S> {
        let (n, s, arena) = (self.n(), self.scaling, self.arena);
        let root: AVec<f64> = (0..n)
            .map(|i| (s.force_scale[i] / s.qdot_std[i]).sqrt())
            .collect_in(arena);
        let w: AVec<S> = (0..n).map(|i| x.qd()[i].scale(root[i])).collect_in(arena);
        let l = |i: usize, j: usize| nets.damping(tri_index(i, j));
        // v = Lᵀ w, then L v + ε w.
        let v: AVec<S> = (0..n)
            .map(|a| {
                (a..n)
                    .map(|b| l(b, a) * w[b].clone())
                    .reduce(|p, q| p + q)
                    .expect("n ≥ 1")
            })
            .collect_in(arena);
        (0..n)
            .map(|a| {
                let lv = (0..=a)
                    .map(|b| l(a, b) * v[b].clone())
                    .reduce(|p, q| p + q)
                    .expect("n ≥ 1");
                -(lv + w[a].scale(PASSIVE_EPS)).scale(root[a])
            })
            .collect_in(arena)
    }
}

/// a += b, entry by entry.
fn add_to<S: Scalar>(a: &mut [S], b: &[S]) {
    for (a, b) in a.iter_mut().zip(b) {
        *a = a.clone() + b.clone();
    }
}
