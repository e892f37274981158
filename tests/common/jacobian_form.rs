//! A robot's M(q) = Σ Jᵢᵀ 𝕀ᵢ Jᵢ and V(q) = −Σ gᵀ(mᵢ pᵢ + Rᵢ hᵢ) from forward kinematics of its own
//! (docs/robots.md#mass-matrix-and-potential): each body's rotation Rᵢ (body to world), origin
//! pᵢ and joint axis zᵢ in the world by Rodrigues' formula on the tree's joint frames, and body
//! i's velocity per unit q̇ⱼ in its own axes, Rᵢᵀ(zⱼ × (pᵢ − pⱼ), zⱼ) (revolute) or Rᵢᵀ(zⱼ, 0)
//! (prismatic). The library's algorithms compose Plücker transforms instead; what this shares
//! with them is only the reader's tree, which Pinocchio's fixtures check.

use graybox::physics::multibody::spatial::Inertial;
use graybox::physics::scalar::Scalar;
use graybox::physics::urdf::{JointKind, Tree};

type V3<S> = [S; 3];
type M3<S> = [[S; 3]; 3];

fn add<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| a[i].clone() + b[i].clone())
}

fn sub<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| a[i].clone() - b[i].clone())
}

fn dot<S: Scalar>(a: &V3<S>, b: &V3<S>) -> S {
    a[0].clone() * b[0].clone() + a[1].clone() * b[1].clone() + a[2].clone() * b[2].clone()
}

fn cross<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [
        a[1].clone() * b[2].clone() - a[2].clone() * b[1].clone(),
        a[2].clone() * b[0].clone() - a[0].clone() * b[2].clone(),
        a[0].clone() * b[1].clone() - a[1].clone() * b[0].clone(),
    ]
}

fn mv<S: Scalar>(m: &M3<S>, x: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| dot(&m[i], x))
}

fn transpose<S: Scalar>(m: &M3<S>) -> M3<S> {
    std::array::from_fn(|i| std::array::from_fn(|j| m[j][i].clone()))
}

fn mm<S: Scalar>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    let bt = transpose(b);
    std::array::from_fn(|i| std::array::from_fn(|j| dot(&a[i], &bt[j])))
}

/// Each body's rotation, origin and joint axis in the world.
struct Poses<S> {
    rot: Vec<M3<S>>,
    pos: Vec<V3<S>>,
    axis: Vec<V3<S>>,
}

fn poses<S: Scalar>(tree: &Tree, q: &[S]) -> Poses<S> {
    let zero = q[0].lift(0.0);
    let vec = |v: [f64; 3]| v.map(|x| zero.lift(x));
    let mat = |m: [[f64; 3]; 3]| m.map(|r| r.map(|x| zero.lift(x)));
    let mut p = Poses {
        rot: vec![],
        pos: vec![],
        axis: vec![],
    };
    for b in &tree.bodies {
        let (joint_rot, joint_pos) = match b.parent {
            None => (mat(b.rot), vec(b.pos)),
            Some(k) => (
                mm(&p.rot[k], &mat(b.rot)),
                add(&p.pos[k], &mv(&p.rot[k], &vec(b.pos))),
            ),
        };
        let axis = mv(&joint_rot, &vec(b.axis));
        let qi = b.drive.value(q);
        let (rot, pos) = match b.kind {
            JointKind::Prismatic => {
                let slide = axis.clone().map(|a| a * qi.clone());
                (joint_rot, add(&joint_pos, &slide))
            }
            JointKind::Revolute | JointKind::Continuous => {
                // R = a aᵀ + cos q (𝟙 − a aᵀ) + sin q [a]×
                let (c, s, a) = (qi.cos(), qi.sin(), b.axis);
                let k = [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]];
                let r: M3<S> = std::array::from_fn(|i| {
                    std::array::from_fn(|j| {
                        let id = if i == j { 1.0 } else { 0.0 };
                        (c.clone().scale(id - a[i] * a[j]) + s.clone().scale(k[i][j]))
                            .shift(a[i] * a[j])
                    })
                });
                (mm(&joint_rot, &r), joint_pos)
            }
        };
        p.rot.push(rot);
        p.pos.push(pos);
        p.axis.push(axis);
    }
    p
}

/// M(q), n×n over the coordinates: with G = ∂(joint values)/∂q, M = Gᵀ M_joints G.
pub fn mass_matrix<S: Scalar>(tree: &Tree, inertia: &[Inertial<S>], q: &[S]) -> Vec<Vec<S>> {
    let n = tree.coordinates.len();
    let p = poses(tree, q);
    let mut m: Vec<Vec<S>> = vec![vec![q[0].lift(0.0); n]; n];
    for (i, body) in inertia.iter().enumerate() {
        let rt = transpose(&p.rot[i]);
        let mut columns: Vec<(usize, V3<S>, Option<V3<S>>)> = vec![];
        let mut j = Some(i);
        while let Some(k) = j {
            let z = &p.axis[k];
            let (v, w) = match tree.bodies[k].kind {
                JointKind::Prismatic => (z.clone(), None),
                _ => (cross(z, &sub(&p.pos[i], &p.pos[k])), Some(z.clone())),
            };
            columns.push((k, mv(&rt, &v), w.map(|w| mv(&rt, &w))));
            j = tree.bodies[k].parent;
        }
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
                let e = e.scale(dj.multiplier * dk.multiplier * twice);
                let (r, c) = (cj.min(ck), cj.max(ck));
                m[r][c] = m[r][c].clone() + e;
            }
        }
    }
    (0..n)
        .map(|r| (0..n).map(|c| m[r.min(c)][r.max(c)].clone()).collect())
        .collect()
}

/// V(q) = −Σ gᵀ(mᵢ pᵢ + Rᵢ hᵢ).
pub fn potential<S: Scalar>(
    tree: &Tree,
    inertia: &[Inertial<S>],
    gravity: &[f64; 3],
    q: &[S],
) -> S {
    let p = poses(tree, q);
    let g = gravity.map(|x| q[0].lift(x));
    let mut v = q[0].lift(0.0);
    for (i, b) in inertia.iter().enumerate() {
        let moment = add(
            &p.pos[i].clone().map(|x| x * b.mass.clone()),
            &mv(&p.rot[i], &b.h),
        );
        v = v - dot(&g, &moment);
    }
    v
}
