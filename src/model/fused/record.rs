//! One block of rows' step recorded on a tape: the model's parameters as tape values (the
//! networks' layers by their place in the flat parameter row, every other value one
//! parameter node each), the networks as tape nodes, and the rest the generic assembly,
//! dynamics and integrator run on [`Var`].

use std::cell::RefCell;
use std::ops::Range;
use std::rc::Rc;

use super::Layout;
use crate::arena::Arena;
use crate::model::spec::ModelSpec;
use crate::model::{ModelConfig, names};
use crate::physics::assembly::{Columns, Networks, Structure, Values};
use crate::physics::dual::{Dual, WIDTH, groups};
use crate::physics::dynamics::{acceleration, residual};
use crate::physics::integrator::States;
use crate::physics::multibody;
use crate::physics::scalar::Scalar;
use crate::physics::tape::{Layer, Tape, Var, forward_dynamics, inverse_dynamics, mlp};
use crate::physics::templates::Template;
use crate::physics::urdf::delay::delayed;

/// The tape's view of the parameters.
struct Recorded {
    mass_const: Option<Vec<Var>>,
    potential_quad: Option<Vec<Var>>,
    b_const: Option<Vec<Var>>,
    eta: Option<Vec<Var>>,
    /// Natural values (positive ones exponentiated), unless the file holds them as they are.
    physical: Option<Vec<Var>>,
}

/// The networks' outputs for the block; M's and V's with their q-tangents, per group of
/// directions (`dual::groups`).
struct TapeNets {
    mass: Option<Vec<Vec<Dual<Var>>>>,
    potential: Option<Vec<Dual<Var>>>,
    force: Option<Vec<Dual<Var>>>,
    damping: Option<Vec<Dual<Var>>>,
}

impl Networks<Var> for TapeNets {
    fn mass(&self, j: usize, dirs: Range<usize>) -> Dual<Var> {
        self.mass.as_ref().expect("mass outputs")[dirs.start / WIDTH][j].clone()
    }
    fn potential_grad(&self, k: usize) -> Var {
        let v = &self.potential.as_ref().expect("potential outputs")[k / WIDTH];
        v.tangent(k % WIDTH)
            .cloned()
            .unwrap_or_else(|| v.v.lift(0.0))
    }
    fn force(&self, j: usize) -> Var {
        self.force.as_ref().expect("force outputs")[j].v.clone()
    }
    fn damping(&self, j: usize) -> Var {
        self.damping.as_ref().expect("damping outputs")[j].v.clone()
    }
}

/// What a block's step is recorded from: the model and where its values sit, and the
/// robot whose algorithms give q̈ when they do (`ModelSpec::multibody`).
pub(super) struct Recipe<'a> {
    pub config: &'a ModelConfig,
    pub layout: &'a Layout,
    pub robot: Option<&'a multibody::Model>,
}

/// x' of the block's states `x` (nq + nv columns) under inputs `u` (m columns): RK4 on the
/// configuration space as inference steps it (`Integrator::step`). With `scale` (a column of
/// each row's Δt_i / Δt), row i steps Δt_i: RK4 of step Δt on the field scaled by Δt_i / Δt
/// is RK4 of step Δt_i on the field, stage for stage (the held input makes it autonomous).
pub(super) fn step(
    recipe: &Recipe<'_>,
    tape: &Rc<RefCell<Tape>>,
    x: &[Var],
    u: &[Var],
    scale: Option<&Var>,
) -> Vec<Var> {
    let config = recipe.config;
    let nq = config.nq();
    let values = record_values(config, recipe.layout, tape);
    let states = States::new(&config.space, 1);
    config
        .integrator
        .step(&states, &x.to_vec(), config.dt, |x: &Vec<Var>| {
            let (q, qd) = x.split_at(nq);
            let mut dx = qd.to_vec();
            dx.extend(dynamics(recipe, &values, (q, qd, u), None));
            match scale {
                Some(s) => dx.into_iter().map(|d| d * s.clone()).collect(),
                None => dx,
            }
        })
}

/// The torque loss's errors of the block's rows (docs/training.md#torque-loss): the
/// manipulator equation's residual M q̈ + c + ∂V/∂q − F(q, q̇, u) at measured (q, q̇, q̈) and
/// the inputs' block `efforts`, joint j's divided by `scale[j]`.
pub(super) fn torque(
    recipe: &Recipe<'_>,
    tape: &Rc<RefCell<Tape>>,
    (q, qd, qdd): (&[Var], &[Var], &[Var]),
    efforts: &[Var],
    scale: &[f64],
) -> Vec<Var> {
    let values = record_values(recipe.config, recipe.layout, tape);
    let u = acting_efforts(recipe.config, &values, tape, efforts);
    let r = dynamics(recipe, &values, (q, qd, &u), Some(qdd));
    (r.into_iter().zip(scale))
        .map(|(r, s)| r.scale(1.0 / s))
        .collect()
}

/// The efforts acting over each row's step: the block as it is, or under the robot's
/// effort delay δ the mean of the log's held samples shifted by δ (`urdf::delay`), recorded
/// as u₀ + δ u₁ with δ's tangent u₁ = ∂u/∂δ at its value: the weights are linear in δ about
/// it. The samples are data, whose gradient nothing asks for.
fn acting_efforts(
    config: &ModelConfig,
    r: &Recorded,
    tape: &Rc<RefCell<Tape>>,
    efforts: &[Var],
) -> Vec<Var> {
    let delay = match (config.template(), r.physical.as_deref()) {
        (Some(Template::Urdf(t)), Some(p)) => t.effort_delay(p),
        _ => None,
    };
    let Some(delay) = delay.filter(|_| config.effort_lags() > 0) else {
        return efforts.to_vec();
    };
    let (m, at) = (config.m, delay.values()[0]);
    let columns: Vec<Vec<f64>> = efforts.iter().map(Var::values).collect();
    let rows = columns[0].len();
    let (mut u0, mut u1) = (vec![vec![0.0; rows]; m], vec![vec![0.0; rows]; m]);
    let mut block = vec![0.0; efforts.len()];
    for i in 0..rows {
        block.iter_mut().zip(&columns).for_each(|(b, c)| *b = c[i]);
        let (u, du) = delayed(&block, m, at);
        for j in 0..m {
            (u0[j][i], u1[j][i]) = (u[j] - at * du[j], du[j]);
        }
    }
    (u0.into_iter().zip(u1))
        .map(|(u0, u1)| Var::input(tape, u0) + delay.clone() * Var::input(tape, u1))
        .collect()
}

fn record_values(config: &ModelConfig, layout: &Layout, tape: &Rc<RefCell<Tape>>) -> Recorded {
    let vars = |name: &str| -> Option<Vec<Var>> {
        let (at, len) = layout.array(name)?;
        Some((at..at + len).map(|i| Var::param(tape, i)).collect())
    };
    let physical = match (vars(names::PHYSICAL), config.template()) {
        (Some(raw), Some(t)) => Some(t.physical_from_raw(&raw)),
        (None, _) => vars(names::PHYSICAL_VALUES),
        (Some(raw), None) => Some(raw),
    };
    Recorded {
        mass_const: vars(names::MASS_CONST),
        potential_quad: vars(names::POTENTIAL_QUAD),
        b_const: vars(names::B_CONST),
        eta: vars(names::ETA),
        physical,
    }
}

/// v̇ of the block, or with `qdd` the manipulator equation's residual at it: the naive
/// network (whose residual is its acceleration's error: it has no M; the service refuses
/// the torque loss for it), or the structure assembled from the spec.
fn dynamics(
    recipe: &Recipe<'_>,
    r: &Recorded,
    (q, qd, u): (&[Var], &[Var], &[Var]),
    qdd: Option<&[Var]>,
) -> Vec<Var> {
    let (config, layout) = (recipe.config, recipe.layout);
    let sc = &config.scaling;
    let space = &config.space;
    let full = || -> Vec<Dual<Var>> {
        (sc.full_features(q, qd, u, space).into_iter())
            .map(Dual::constant)
            .collect()
    };
    let net = |name: &str, x: &[Dual<Var>], dirs: usize| -> Option<Vec<Dual<Var>>> {
        let layers: &[Layer] = layout.net(name)?;
        Some(mlp(layers, x, dirs))
    };
    let ModelSpec::Structured {
        mass,
        potential,
        forces,
        ..
    } = &config.spec
    else {
        let out = net(names::NAIVE, &full(), 0).expect("a naive model's network");
        let acc = (out.into_iter().enumerate())
            .map(|(j, o)| o.v.scale(sc.acc_std[j]).shift(sc.acc_mean[j]));
        return match qdd {
            None => acc.collect(),
            Some(qdd) => acc.zip(qdd).map(|(a, m)| a - m.clone()).collect(),
        };
    };
    let n = config.nv();
    // M's and V's networks read q with its ∂/∂q along each velocity, a group at a time.
    let q_in: Vec<_> =
        (groups::<Var>(n).map(|dirs| (dirs.len(), sc.q_features(q, space, dirs)))).collect();
    let of_q = |name: &str| -> Option<Vec<Vec<Dual<Var>>>> {
        (q_in.iter().map(|(dirs, x)| net(name, x, *dirs))).collect()
    };
    let nets = TapeNets {
        mass: of_q(names::MASS_NET),
        potential: of_q(names::POTENTIAL_NET)
            .map(|groups| groups.into_iter().map(|mut v| v.remove(0)).collect()),
        force: net(names::FORCE_NET, &full(), 0)
            .or_else(|| net(names::B_NET, &sc.q_features(q, space, 0..0), 0)),
        // [q, q̇]: the full input without u's last m entries.
        damping: layout.net(names::DAMPING_NET).map(|_| {
            let mut x = full();
            x.truncate(x.len() - u.len());
            net(names::DAMPING_NET, &x, 0).expect("the layout has it")
        }),
    };
    let structure = Structure {
        mass,
        potential,
        forces,
        template: config.template(),
        scaling: sc,
        values: Values {
            mass_const: r.mass_const.as_deref(),
            potential_quad: r.potential_quad.as_deref(),
            b_const: r.b_const.as_deref(),
            eta: r.eta.as_deref(),
            physical: r.physical.as_deref(),
        },
        space,
        m: config.m,
        arena: &Arena::new(),
    };
    let inputs = Columns { q, qd, u };
    if let (Some(robot), Some((urdf, _))) = (recipe.robot, config.spec.multibody()) {
        let tau = structure.multibody_torques(&nets, &inputs);
        let physical = r
            .physical
            .as_deref()
            .expect("a template's M has physical values");
        let pi = urdf.standard_parameters(physical);
        return match qdd {
            None => forward_dynamics(robot, q, qd, &tau, &pi),
            Some(qdd) => (inverse_dynamics(robot, q, qd, qdd, &pi).into_iter())
                .zip(tau.iter())
                .map(|(id, t)| id - t.clone())
                .collect(),
        };
    }
    let t = structure.terms(&nets, &inputs);
    let grad_v = t.grad_v.as_deref();
    match qdd {
        None => acceleration(&t.factor, grad_v, &t.forces, qd).to_vec(),
        Some(qdd) => residual(&t.factor, grad_v, &t.forces, qd, qdd).to_vec(),
    }
}
