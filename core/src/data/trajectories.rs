//! A dataset's trajectories: the boundaries it was uploaded with (trajectory form), or else
//! the maximal chains of rows where one row's next state is the following row's state
//! exactly (flat transitions cut from recordings keep their order).

use super::Dataset;
use crate::rng::Rng;

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
    // Row i of `a` against row i + 1 of `b` (rows of n), bit for bit.
    let same = |a: &[f64], b: &[f64], n: usize, i: usize| {
        a[i * n..(i + 1) * n]
            .iter()
            .zip(&b[(i + 1) * n..(i + 2) * n])
            .all(|(x, y)| x.to_bits() == y.to_bits())
    };
    let follows = |i: usize| same(&d.q_next, &d.q, d.nq, i) && same(&d.qdot_next, &d.qdot, d.nv, i);
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

impl Dataset {
    /// A seeded split into (train, validation) that keeps trajectories whole, for training on
    /// windows of several steps (a row split would break every chain): whole trajectories,
    /// drawn in a seeded order, go to validation until it holds round(fraction·count)
    /// transitions (at least one trajectory, never all). Data that is one trajectory is cut
    /// in time instead: its last round(fraction·count) transitions validate. Both parts keep
    /// their trajectory boundaries.
    pub fn split_by_trajectories(&self, fraction: f64, seed: u64) -> (Dataset, Dataset) {
        let count = self.count();
        let want = ((fraction * count as f64).round() as usize).clamp(1, count.max(2) - 1);
        let segments: Vec<Segment> = self
            .segments()
            .into_iter()
            .filter(|s| s.length > 0)
            .collect();
        if segments.len() < 2 {
            let cut = count - want;
            let part = |rows: std::ops::Range<usize>| {
                let len = rows.len();
                let idx: Vec<usize> = rows.collect();
                let d = self.subset(&idx);
                d.with_trajectories(vec![len])
                    .expect("one trajectory of all its rows")
            };
            return (part(0..cut), part(cut..count));
        }
        let mut order: Vec<usize> = (0..segments.len()).collect();
        Rng::derive(seed, 0x5_9117).shuffle(&mut order);
        let mut is_val = vec![false; segments.len()];
        let mut held = 0;
        for &k in order.iter().take(segments.len() - 1) {
            if held >= want {
                break;
            }
            is_val[k] = true;
            held += segments[k].length;
        }
        let part = |val: bool| {
            let chosen: Vec<&Segment> = (segments.iter().zip(&is_val))
                .filter(|(_, v)| **v == val)
                .map(|(s, _)| s)
                .collect();
            let idx: Vec<usize> = chosen
                .iter()
                .flat_map(|s| s.start..s.start + s.length)
                .collect();
            let lengths = chosen.iter().map(|s| s.length).collect();
            (self.subset(&idx))
                .with_trajectories(lengths)
                .expect("the chosen trajectories' rows")
        };
        (part(false), part(true))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(states: &[f64], next: &[f64]) -> Dataset {
        let k = states.len();
        Dataset::new(
            0.1,
            (1, 1),
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
    fn a_trajectory_split_keeps_trajectories_whole() {
        let states: Vec<f64> = (0..10).map(f64::from).collect();
        let next: Vec<f64> = (1..11).map(f64::from).collect();
        let d = data(&states, &next)
            .with_trajectories(vec![4, 2, 4])
            .unwrap();
        let (train, val) = d.split_by_trajectories(0.3, 1);
        let (lt, lv) = (
            train.trajectories.clone().unwrap(),
            val.trajectories.clone().unwrap(),
        );
        assert_eq!(train.count() + val.count(), 10);
        assert!(
            lv.iter().sum::<usize>() >= 3 && !lt.is_empty(),
            "{lt:?} {lv:?}"
        );
        // Each part's trajectories are rows that chained in the original: still chains.
        for part in [&train, &val] {
            let chained: Vec<usize> = chains(part).iter().map(|s| s.length).collect();
            let given = part.trajectories.clone().unwrap();
            assert!(chained.len() <= given.len(), "{chained:?} {given:?}");
        }
        let mut sizes = [lt, lv].concat();
        sizes.sort();
        assert_eq!(sizes, [2, 4, 4]);
        // One trajectory is cut in time: the last 30% validates.
        let one = data(&states, &next).with_trajectories(vec![10]).unwrap();
        let (train, val) = one.split_by_trajectories(0.3, 1);
        assert_eq!(train.q, states[..7]);
        assert_eq!(val.q, states[7..]);
        assert_eq!(val.trajectories, Some(vec![3]));
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
