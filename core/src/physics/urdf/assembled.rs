//! The rigid-body tree's M(q) and V(q) over any scalar: forward kinematics from the joint
//! values, then M = Σ_bodies Jᵢᵀ 𝕀ᵢ Jᵢ with each body's Jacobian and spatial inertia in its
//! own frame, and V = −Σ gᵀ(mᵢ pᵢ + Rᵢ hᵢ). Dual numbers give their q-derivatives (the
//! Coriolis term needs ∂M/∂q), so the same code serves training, inference, linearization.

use super::tree::{JointKind, Tree};
use crate::physics::multibody::spatial::{BodyInertia, M3, V3, add, cross, dot, mm, mtv, mv, sub};
use crate::physics::multibody::term::{C, Term, V, constant_mat, constant_vec};
use crate::physics::scalar::Scalar;

/// A 3-vector of terms.
type Vec3<S> = V3<Term<S>>;

/// Each body's frame in the world: rotation, origin, and its joint's axis in world axes.
struct Poses<S> {
    rot: Vec<M3<Term<S>>>,
    pos: Vec<V3<Term<S>>>,
    axis: Vec<V3<Term<S>>>,
}

/// R = a aᵀ + cos q (𝟙 − a aᵀ) + sin q [a]×, the rotation by q about the unit axis a.
fn rotation<S: Scalar>(a: &[f64; 3], q: &S) -> M3<Term<S>> {
    let (c, s) = (V(q.cos()), V(q.sin()));
    let k = [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let aa = a[i] * a[j];
            let id = if i == j { 1.0 } else { 0.0 };
            C(aa) + c.clone() * C(id - aa) + s.clone() * C(k[i][j])
        })
    })
}

fn poses<S: Scalar>(tree: &Tree, q: &[S]) -> Poses<S> {
    let n = tree.bodies.len();
    let mut p = Poses {
        rot: Vec::with_capacity(n),
        pos: Vec::with_capacity(n),
        axis: Vec::with_capacity(n),
    };
    for b in &tree.bodies {
        let (joint_rot, joint_pos) = match b.parent {
            None => (constant_mat(b.rot), constant_vec(b.pos)),
            Some(k) => (
                mm(&p.rot[k], &constant_mat(b.rot)),
                add(&p.pos[k], &mv(&p.rot[k], &constant_vec(b.pos))),
            ),
        };
        let axis = mv(&joint_rot, &constant_vec(b.axis));
        let qi = b.drive.value(q);
        let (rot, pos) = match b.kind {
            JointKind::Prismatic => {
                let slide = axis.clone().map(|a| a * V(qi.clone()));
                (joint_rot, add(&joint_pos, &slide))
            }
            JointKind::Revolute | JointKind::Continuous => {
                (mm(&joint_rot, &rotation(&b.axis, &qi)), joint_pos)
            }
        };
        p.rot.push(rot);
        p.pos.push(pos);
        p.axis.push(axis);
    }
    p
}

/// The bodies from `i` to the root: the joints whose motion moves body i.
fn chain(tree: &Tree, i: usize) -> Vec<usize> {
    let mut out = vec![i];
    while let Some(k) = tree.bodies[*out.last().expect("non-empty")].parent {
        out.push(k);
    }
    out
}

/// M(q), n×n over the coordinates: with G = ∂(joint values)/∂q (one entry per joint, its
/// mimic multiplier), M = Gᵀ M_joints G.
pub fn mass_matrix<S: Scalar>(tree: &Tree, inertia: &[BodyInertia<S>], q: &[S]) -> Vec<Vec<S>> {
    let n = tree.coordinates.len();
    let p = poses(tree, q);
    let mut m: Vec<Vec<Term<S>>> = vec![vec![C(0.0); n]; n];
    for (i, body) in inertia.iter().enumerate() {
        let joints = chain(tree, i);
        // Body i's velocity per unit q̇_j, in its own frame: (v of its origin, ω).
        let columns: Vec<(usize, Vec3<S>, Option<Vec3<S>>)> = joints
            .iter()
            .map(|&j| {
                let z = &p.axis[j];
                let (v, w) = match tree.bodies[j].kind {
                    JointKind::Prismatic => (z.clone(), None),
                    _ => (cross(z, &sub(&p.pos[i], &p.pos[j])), Some(z.clone())),
                };
                (j, mtv(&p.rot[i], &v), w.map(|w| mtv(&p.rot[i], &w)))
            })
            .collect();
        for (a, (j, vj, wj)) in columns.iter().enumerate() {
            for (k, vk, wk) in &columns[a..] {
                // m vⱼ·vₖ + vⱼ·(ωₖ × h) + vₖ·(ωⱼ × h) + ωⱼᵀ Ī ωₖ
                let mut e = body.mass.clone() * dot(vj, vk);
                if let Some(wk) = wk {
                    e = e + dot(vj, &cross(wk, &body.h));
                }
                if let Some(wj) = wj {
                    e = e + dot(vk, &cross(wj, &body.h));
                    if let Some(wk) = wk {
                        e = e + dot(wj, &mv(&body.inertia, wk));
                    }
                }
                let (dj, dk) = (tree.bodies[*j].drive, tree.bodies[*k].drive);
                let (cj, ck) = (dj.coordinate, dk.coordinate);
                // Joints j ≠ k of one coordinate: both (j, k) and (k, j) land on its diagonal.
                let twice = if j != k && cj == ck { 2.0 } else { 1.0 };
                let g = dj.multiplier * dk.multiplier * twice;
                if g != 1.0 {
                    e = e * C(g);
                }
                let (r, c) = (cj.min(ck), cj.max(ck));
                m[r][c] = m[r][c].clone() + e;
            }
        }
    }
    let like = &q[0];
    (0..n)
        .map(|r| {
            (0..n)
                .map(|c| m[r.min(c)][r.max(c)].clone().value(like))
                .collect()
        })
        .collect()
}

/// V(q) = −Σ gᵀ(mᵢ pᵢ + Rᵢ hᵢ).
pub fn potential<S: Scalar>(
    tree: &Tree,
    inertia: &[BodyInertia<S>],
    gravity: &[f64; 3],
    q: &[S],
) -> S {
    let p = poses(tree, q);
    let g = constant_vec::<S>(*gravity);
    let v = inertia
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let moment = add(
                &p.pos[i].clone().map(|x| x * b.mass.clone()),
                &mv(&p.rot[i], &b.h),
            );
            -dot(&g, &moment)
        })
        .reduce(|a, b| a + b)
        .expect("a tree has a body");
    v.value(&q[0])
}
