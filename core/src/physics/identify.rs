//! Which products of a template's parameters data can determine
//! (docs/dynamics.md#identifiability-of-formula-templates): from ∂q̈/∂ log θ at sampled states,
//! the directions of log θ along which q̈ does not change (the Jacobian's null space), and the
//! simplest products Π θⱼ^aⱼ (small integer aⱼ) that stay constant along all of them.

use super::eigen::symmetric_eigen;

/// Each factor's power in a candidate product.
const POWERS: [i32; 4] = [1, -1, 2, -2];
/// Factors per candidate product.
const MAX_FACTORS: usize = 3;
/// Beyond this many parameters nothing is searched: the candidates grow as p³ and the
/// eigen-decomposition as p³ per sweep, and a document may hold thousands of parameters.
pub const MAX_PARAMS: usize = 32;
/// An eigenvalue of JᵀJ below this fraction of the largest is a direction the data cannot
/// see. The Jacobian is a central difference with a relative error of ~1e-8, so a true null
/// direction's eigenvalue is ~1e-16 of the largest, and a real but weak effect stays above.
const NULL_TOL: f64 = 1e-9;
/// The largest component a (unit) exponent vector may have along a null direction: the
/// null directions carry the difference's error, ~1e-8, and a product off by one factor
/// leans ~0.3 into one.
const ALIGN_TOL: f64 = 1e-4;

/// An identifiable product: (parameter index, power) for each factor.
#[derive(Debug, Clone, PartialEq)]
pub struct Product(pub Vec<(usize, i32)>);

impl Product {
    /// As the built-in templates name theirs: "g/l", "b/(m*l^2)", "m*l^2".
    pub fn name(&self, names: &[&str]) -> String {
        let factor = |&(i, a): &(usize, i32)| match a.abs() {
            1 => names[i].to_string(),
            k => format!("{}^{k}", names[i]),
        };
        let up: Vec<String> = self.0.iter().filter(|f| f.1 > 0).map(factor).collect();
        let down: Vec<String> = self.0.iter().filter(|f| f.1 < 0).map(factor).collect();
        let up = if up.is_empty() {
            "1".to_string()
        } else {
            up.join("*")
        };
        match down.len() {
            0 => up,
            1 => format!("{up}/{}", down[0]),
            _ => format!("{up}/({})", down.join("*")),
        }
    }

    pub fn value(&self, values: &[f64]) -> f64 {
        self.0.iter().map(|&(i, a)| values[i].powi(a)).product()
    }
}

/// `rows`: ∂(output)/∂ log θⱼ, one row per output (each sampled state's q̈ᵢ) and one column
/// per parameter considered. Returns independent identifiable products, simplest first
/// (fewer factors, then lower powers), and the rank: how many independent combinations the
/// data determines. Fewer products than the rank: the rest are not simple products. Nothing
/// (and rank 0) beyond `MAX_PARAMS` parameters.
pub fn identifiable_products(rows: &[Vec<f64>], p: usize) -> (Vec<Product>, usize) {
    if p > MAX_PARAMS {
        return (vec![], 0);
    }
    let null = null_space(rows, p);
    let rank = p - null.len();
    let (mut chosen, mut basis) = (vec![], Vec::<Vec<f64>>::new());
    for a in candidates(p) {
        if chosen.len() == rank {
            break;
        }
        let len = a.iter().map(|&x| f64::from(x * x)).sum::<f64>().sqrt();
        let unit: Vec<f64> = a.iter().map(|&x| f64::from(x) / len).collect();
        if null.iter().any(|n| dot(n, &unit).abs() > ALIGN_TOL) {
            continue;
        }
        // Independent of the products chosen so far (Gram–Schmidt).
        let mut r = unit;
        for b in &basis {
            let d = dot(b, &r);
            r.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
        }
        let rn = dot(&r, &r).sqrt();
        if rn < 1e-6 {
            continue;
        }
        basis.push(r.iter().map(|x| x / rn).collect());
        let factors = (a.iter().enumerate()).filter(|(_, x)| **x != 0);
        chosen.push(Product(factors.map(|(i, &x)| (i, x)).collect()));
    }
    (chosen, rank)
}

/// An orthonormal basis of the directions in which the rows (each scaled to unit length, so
/// that every output weighs alike whatever its units) do not change.
fn null_space(rows: &[Vec<f64>], p: usize) -> Vec<Vec<f64>> {
    let mut g = vec![vec![0.0; p]; p];
    for r in rows {
        let n2 = dot(r, r);
        if !(n2 > 0.0 && n2.is_finite()) {
            continue;
        }
        for i in 0..p {
            for j in 0..p {
                g[i][j] += r[i] * r[j] / n2;
            }
        }
    }
    let (values, vectors) = symmetric_eigen(&g);
    let top = values.iter().copied().fold(0.0, f64::max);
    (0..p)
        .filter(|&k| values[k] <= NULL_TOL * top)
        .map(|k| (0..p).map(|i| vectors[i][k]).collect())
        .collect()
}

/// Exponent vectors of up to `MAX_FACTORS` factors, simplest first; each up to sign once (its
/// first power positive) and none a multiple of another (not every power even).
fn candidates(p: usize) -> Vec<Vec<i32>> {
    let mut out = vec![];
    let mut stack: Vec<(usize, Vec<(usize, i32)>)> = vec![(0, vec![])];
    while let Some((from, factors)) = stack.pop() {
        if !factors.is_empty() && factors.iter().any(|f| f.1 % 2 != 0) {
            let mut a = vec![0; p];
            factors.iter().for_each(|&(i, x)| a[i] = x);
            out.push(a);
        }
        if factors.len() == MAX_FACTORS {
            continue;
        }
        for i in from..p {
            for x in POWERS {
                if factors.is_empty() && x < 0 {
                    continue;
                }
                let mut next = factors.clone();
                next.push((i, x));
                stack.push((i + 1, next));
            }
        }
    }
    let weight = |a: &Vec<i32>| {
        let factors = a.iter().filter(|x| **x != 0).count();
        let power: i32 = a.iter().map(|x| x.abs()).sum();
        let place: Vec<usize> = (a.iter().enumerate())
            .filter(|(_, x)| **x != 0)
            .map(|(i, _)| i)
            .collect();
        (factors, power, place, a.clone())
    };
    out.sort_by_cached_key(weight);
    out
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
