//! The dataset as a JSON file (`Dataset::to_json`): the trajectory form when it has
//! trajectories, else transitions; each transition's Δt when they differ.

use serde::Serialize;

use crate::data::Dataset;
use crate::data::trajectories::Segment;

/// Δt as a file writes it: one for all, or each transition's.
#[derive(Serialize)]
#[serde(untagged)]
enum StepsJson<'a> {
    One(f64),
    Each(&'a [f64]),
}

#[derive(Serialize)]
struct DatasetJson<'a> {
    dt: StepsJson<'a>,
    q: Vec<&'a [f64]>,
    qdot: Vec<&'a [f64]>,
    u: Vec<&'a [f64]>,
    q_next: Vec<&'a [f64]>,
    qdot_next: Vec<&'a [f64]>,
}

#[derive(Serialize)]
struct TrajectoriesJson<'a> {
    #[serde(skip_serializing_if = "Option::is_none")]
    dt: Option<f64>,
    trajectories: Vec<TrajectoryJson<'a>>,
}

#[derive(Serialize)]
struct TrajectoryJson<'a> {
    /// The states' times from 0, when the steps differ.
    #[serde(skip_serializing_if = "Option::is_none")]
    t: Option<Vec<f64>>,
    q: Vec<&'a [f64]>,
    qdot: Vec<&'a [f64]>,
    u: Vec<&'a [f64]>,
}

/// Rows `a..b` of the states, then the last row's next state: a trajectory's T + 1 states.
fn states<'d>(now: &'d [f64], next: &'d [f64], a: usize, b: usize, n: usize) -> Vec<&'d [f64]> {
    let mut r: Vec<&[f64]> = now[a * n..b * n].chunks(n).collect();
    r.push(&next[(b - 1) * n..b * n]);
    r
}

fn rows(a: &[f64], w: usize) -> Vec<&[f64]> {
    a.chunks(w).collect()
}

impl Dataset {
    /// The dataset as a JSON file: in trajectory form when it has trajectories (one without
    /// transitions has nothing to write and is left out), else as transitions.
    pub fn to_json(&self) -> String {
        if self.trajectories.is_some() {
            let trajectories = self.segments().into_iter().filter(|s| s.length > 0);
            return serde_json::to_string(&TrajectoriesJson {
                dt: self.steps.is_none().then_some(self.dt),
                trajectories: trajectories.map(|s| self.trajectory(s)).collect(),
            })
            .expect("plain arrays serialize");
        }
        let dt = match &self.steps {
            Some(s) => StepsJson::Each(s),
            None => StepsJson::One(self.dt),
        };
        serde_json::to_string(&DatasetJson {
            dt,
            q: rows(&self.q, self.nq),
            qdot: rows(&self.qdot, self.nv),
            u: rows(&self.u, self.m),
            q_next: rows(&self.q_next, self.nq),
            qdot_next: rows(&self.qdot_next, self.nv),
        })
        .expect("plain arrays serialize")
    }

    /// One trajectory's states, inputs and (with steps) times.
    fn trajectory(&self, s: Segment) -> TrajectoryJson<'_> {
        let (nq, nv, m) = (self.nq, self.nv, self.m);
        let (a, b) = (s.start, s.start + s.length);
        let t = (self.steps.as_ref()).map(|s| {
            let mut t = vec![0.0];
            t.extend(s[a..b].iter().scan(0.0, |c, d| {
                *c += d;
                Some(*c)
            }));
            t
        });
        TrajectoryJson {
            t,
            q: states(&self.q, &self.q_next, a, b, nq),
            qdot: states(&self.qdot, &self.qdot_next, a, b, nv),
            u: rows(&self.u[a * m..b * m], m),
        }
    }
}
