//! A dataset's trajectories: the boundaries it was uploaded with (trajectory form), or else
//! the maximal chains of rows where one row's next state is the following row's state
//! exactly (flat transitions cut from recordings keep their order).

use super::Dataset;

/// Rows `start .. start + length` of a dataset, one trajectory of `length` transitions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Segment {
    pub index: usize,
    pub start: usize,
    pub length: usize,
}

/// The trajectories of `lengths` transitions each, in order.
pub fn from_lengths(lengths: &[usize]) -> Vec<Segment> {
    let mut start = 0;
    lengths
        .iter()
        .enumerate()
        .map(|(index, &length)| {
            let s = Segment {
                index,
                start,
                length,
            };
            start += length;
            s
        })
        .collect()
}

/// The maximal chains of rows i, i+1, … with (q′, q̇′)ᵢ = (q, q̇)ᵢ₊₁ bit for bit: a recording
/// cut into transitions chains back whole, shuffled or sampled rows are chains of one.
pub fn chains(d: &Dataset) -> Vec<Segment> {
    let n = d.n;
    // Row i of `a` against row i + 1 of `b`, bit for bit.
    let same = |a: &[f64], b: &[f64], i: usize| {
        a[i * n..(i + 1) * n]
            .iter()
            .zip(&b[(i + 1) * n..(i + 2) * n])
            .all(|(x, y)| x.to_bits() == y.to_bits())
    };
    let follows = |i: usize| same(&d.q_next, &d.q, i) && same(&d.qdot_next, &d.qdot, i);
    let mut lengths = vec![];
    let mut length = 0;
    for i in 0..d.count() {
        length += 1;
        if i + 1 == d.count() || !follows(i) {
            lengths.push(length);
            length = 0;
        }
    }
    from_lengths(&lengths)
}

/// The trajectories' lengths of a JSON upload in trajectory form (each trajectory's number of
/// inputs), or None for any other form. Read after the upload parsed, so the shape is known.
pub fn uploaded_lengths(value: &serde_json::Value) -> Option<Vec<usize>> {
    value.get("trajectories")?.as_array().map(|ts| {
        ts.iter()
            .map(|t| t.get("u").and_then(|u| u.as_array()).map_or(0, Vec::len))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(states: &[f64], next: &[f64]) -> Dataset {
        let k = states.len();
        Dataset::new(
            0.1,
            1,
            1,
            [
                states.to_vec(),
                states.to_vec(),
                vec![0.0; k],
                next.to_vec(),
                next.to_vec(),
            ],
        )
        .unwrap()
    }

    #[test]
    fn chains_follow_exact_next_states() {
        // 0→1→2, then 5→6, then 9 alone.
        let d = data(
            &[0.0, 1.0, 2.0, 5.0, 6.0, 9.0],
            &[1.0, 2.0, 3.0, 6.0, 7.0, 10.0],
        );
        let lengths: Vec<usize> = chains(&d).iter().map(|s| s.length).collect();
        assert_eq!(lengths, [3, 2, 1]);
        assert_eq!(
            chains(&d)[1],
            Segment {
                index: 1,
                start: 3,
                length: 2
            }
        );
        // One ulp off breaks the chain: exact means exact.
        let off = data(&[0.0, f64::from_bits(1.0f64.to_bits() + 1)], &[1.0, 2.0]);
        assert_eq!(chains(&off).len(), 2);
    }

    #[test]
    fn lengths_give_consecutive_segments() {
        let s = from_lengths(&[2, 3]);
        assert_eq!(
            s[1],
            Segment {
                index: 1,
                start: 2,
                length: 3
            }
        );
    }
}
