//! What a structured model says about energy and work (docs/energy.md): the value of its
//! potential V(q), not only ∇V, and its generalized force F split into the parts its spec
//! names, each marked as damping or not. The assembly's other half: one arm per part kind,
//! beside `assembly.rs`'s.

use super::assembly::{Coef, Inputs, Networks, Structure};
use super::dynamics::tri_index;
use super::scalar::Scalar;
use super::templates::Template;
use crate::arena::{AVec, CollectIn, avec};
use crate::physics::parts::{ForceSpec, PotentialSpec};

/// The potential network's (unscaled) output value, which only inference reads: training
/// never needs V itself, only ∇V.
pub trait PotentialValue<S> {
    fn potential_value(&self) -> S;
}

/// One named part of F; the parts of a model sum to its F.
pub struct ForcePart<'a, S> {
    /// `input` (B u), `damping`, `friction`, `unforced` (a formula template's F at u = 0,
    /// which may hold anything), `residual` (a network on a template's F) or `network` (a
    /// whole F from a network).
    pub name: &'static str,
    /// A part the spec names as damping or friction, whatever sign its trained values took:
    /// switched off in the unforced rollouts that measure whether the rest of the model
    /// conserves energy (a learned η > 0 pumping energy in shows in the passivity figure,
    /// which keeps every part on).
    pub dissipation: bool,
    pub values: AVec<'a, S>,
}

impl ForceSpec {
    /// How many parts `force_parts` names.
    pub fn part_count(&self) -> usize {
        match self {
            ForceSpec::Mlp { .. } => 1,
            ForceSpec::ControlAffine { .. }
            | ForceSpec::ConstantAffine
            | ForceSpec::Passive { .. } => 2,
            ForceSpec::Template { residual } => 2 + usize::from(residual.is_some()),
        }
    }
}

impl<'a, P> Structure<'a, P> {
    /// V(q) up to its constant, or only what is not the template's (`template: false`, for a
    /// robot whose gravity the multibody algorithms compute themselves).
    pub fn potential_value<S: Scalar>(
        &self,
        nets: &impl PotentialValue<S>,
        x: &impl Inputs<S>,
        template: bool,
    ) -> S
    where
        P: Coef<S>,
    {
        let q = x.q();
        let zero = q[0].lift(0.0);
        let network = || nets.potential_value().scale(self.scaling.potential_scale());
        match self.potential {
            PotentialSpec::Zero => zero,
            PotentialSpec::Mlp { .. } => network(),
            PotentialSpec::Quadratic => {
                let k = self.values.potential_quad.expect("quadratic potential");
                let mut twice = zero;
                for i in 0..self.n() {
                    for j in 0..self.n() {
                        let kij = &k[tri_index(i.max(j), i.min(j))];
                        twice = twice + kij.times(&(q[i].clone() * q[j].clone()));
                    }
                }
                twice.scale(0.5 * self.scaling.quadratic_scale())
            }
            PotentialSpec::Template { residual } => {
                let own = match template {
                    true => (self.template()).potential_in(self.arena, &self.physical(&q[0]), q),
                    false => zero,
                };
                match residual {
                    None => own,
                    Some(_) => own + network(),
                }
            }
        }
    }

    /// F split into the parts the spec names.
    pub fn force_parts<S: Scalar>(
        &self,
        nets: &impl Networks<S>,
        x: &impl Inputs<S>,
    ) -> AVec<'a, ForcePart<'a, S>>
    where
        P: Coef<S>,
    {
        let a = self.arena;
        let part = |name, dissipation, values| ForcePart {
            name,
            dissipation,
            values,
        };
        match self.forces {
            ForceSpec::Mlp { .. } => avec![in a; part("network", false, self.force_network(nets))],
            ForceSpec::ControlAffine { .. } | ForceSpec::ConstantAffine => {
                let (bu, damping) = self.affine_parts(&self.input_gain(nets, x), x);
                avec![in a; part("input", false, bu), part("damping", true, damping)]
            }
            ForceSpec::Passive { .. } => {
                let bu = self.input_force(&self.input_gain(nets, x), x);
                let damping = self.passive_damping(nets, x);
                avec![in a; part("input", false, bu), part("damping", true, damping)]
            }
            ForceSpec::Template { residual } => {
                let mut parts = self.template_force_parts(x);
                if residual.is_some() {
                    parts.push(part("residual", false, self.force_network(nets)));
                }
                parts
            }
        }
    }

    /// A template's F as B u = F(q, q̇, u) − F(q, q̇, 0) and its unforced rest F(q, q̇, 0):
    /// the built-in templates' is η ∘ q̇ and a robot's its joints' damping and friction; a
    /// formula's may hold anything (a spring, a drive), so it is not named damping.
    fn template_force_parts<S: Scalar>(&self, x: &impl Inputs<S>) -> AVec<'a, ForcePart<'a, S>>
    where
        P: Coef<S>,
    {
        let (t, a) = (self.template(), self.arena);
        let p = self.physical(&x.q()[0]);
        let idle: AVec<S> = x.u().iter().map(|u| u.lift(0.0)).collect_in(a);
        // A robot's actuators' offsets are theirs, not the joints' friction.
        let unforced = match t {
            Template::Urdf(r) => r.passive_forces_in(a, &p, x.qd()),
            _ => t.forces_in(a, &p, x.q(), x.qd(), &idle),
        };
        let all = t.forces_in(a, &p, x.q(), x.qd(), x.u());
        let input = all.into_iter().zip(&unforced).map(|(f, r)| f - r.clone());
        let (name, dissipation) = match t {
            Template::Formula(_) => ("unforced", false),
            Template::Urdf(_) => ("friction", true),
            _ => ("damping", true),
        };
        avec![in a;
            ForcePart {
                name: "input",
                dissipation: false,
                values: input.collect_in(a),
            },
            ForcePart {
                name,
                dissipation,
                values: unforced,
            },
        ]
    }
}
