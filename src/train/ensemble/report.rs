//! What an ensemble reports: its members' means and spreads, and the time the run took.

use std::collections::BTreeMap;

use super::{EnsembleEpoch, LossSpread};
use crate::model::report::{EnsembleReport, EpochMetrics, MemberReport, Spread, TrainReport};

/// The mean of the values when every one is known.
pub(super) fn mean(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let v: Option<Vec<f64>> = values.collect();
    v.filter(|v| !v.is_empty()).map(|v| Spread::of(&v).mean)
}

/// The members' mean and spread of one epoch's losses.
pub(super) fn summary(ran: &[EpochMetrics]) -> EnsembleEpoch {
    let spread = |f: &dyn Fn(&EpochMetrics) -> Option<f64>| -> Option<Spread> {
        let v: Option<Vec<f64>> = ran.iter().map(f).collect();
        v.filter(|v| !v.is_empty()).map(|v| Spread::of(&v))
    };
    let train = spread(&|m| Some(m.train_loss)).expect("a member ran");
    let val = spread(&|m| m.val_loss);
    let val_h = spread(&|m| m.val_horizon_loss);
    EnsembleEpoch {
        mean: EpochMetrics {
            epoch: ran.iter().map(|m| m.epoch).max().unwrap_or(0),
            train_loss: train.mean,
            val_loss: val.map(|s| s.mean),
            val_horizon_loss: val_h.map(|s| s.mean),
            seconds: 0.0,
        },
        std: Some(LossSpread {
            train_loss: train.std,
            val_loss: val.map(|s| s.std),
            val_horizon_loss: val_h.map(|s| s.std),
        }),
    }
}

/// The ensemble's report: member 0's, with the members' mean losses, mean physical values,
/// mean history (by epoch, over the members that ran it), every member's warnings once per
/// code, and the members' own figures with the physical values' spread. Its seconds are the
/// run's: each epoch's wall time (`wall`, by epoch), which members trained side by side share.
pub(super) fn ensemble_report(
    reports: &[&TrainReport],
    wall: &BTreeMap<usize, f64>,
) -> TrainReport {
    let mut r = reports[0].clone();
    let of = |f: &dyn Fn(&TrainReport) -> Option<f64>| mean(reports.iter().map(|r| f(r)));
    r.train_loss = of(&|r| Some(r.train_loss)).unwrap_or(f64::NAN);
    r.val_loss = of(&|r| r.val_loss);
    r.best_val_loss = of(&|r| r.best_val_loss);
    r.epochs = reports.iter().map(|r| r.epochs).max().unwrap_or(0);
    r.stopped_early = reports.iter().all(|r| r.stopped_early);
    let mut physical = BTreeMap::new();
    for name in r.physical_parameters.keys() {
        let values: Vec<f64> = reports
            .iter()
            .map(|m| m.physical_parameters[name])
            .collect();
        physical.insert(name.clone(), Spread::of(&values));
    }
    r.physical_parameters = physical.iter().map(|(k, s)| (k.clone(), s.mean)).collect();
    for (i, c) in r.identifiable.iter_mut().enumerate() {
        let same = |m: &&&TrainReport| m.identifiable.get(i).is_some_and(|o| o.name == c.name);
        if reports.iter().all(|m| same(&m)) {
            c.value = of(&|m| Some(m.identifiable[i].value)).unwrap_or(c.value);
        }
    }
    r.history = (1..=r.epochs)
        .filter_map(|e| {
            let ran: Vec<EpochMetrics> = (reports.iter())
                .filter_map(|m| m.history.iter().find(|h| h.epoch == e).copied())
                .collect();
            (!ran.is_empty()).then(|| {
                let mut s = summary(&ran).mean;
                // A checkpoint from before ensembles kept their wall times: the longest
                // member's epoch, which every member's overlapped when they ran side by side.
                s.seconds = wall
                    .get(&e)
                    .copied()
                    .unwrap_or_else(|| ran.iter().map(|m| m.seconds).fold(0.0, f64::max));
                s
            })
        })
        .collect();
    r.seconds = r.history.iter().map(|h| h.seconds).sum();
    r.warnings = vec![];
    for w in reports.iter().flat_map(|m| &m.warnings) {
        if !r.warnings.iter().any(|o| o.code == w.code) {
            r.warnings.push(w.clone());
        }
    }
    r.ensemble = Some(EnsembleReport {
        members: reports.iter().map(|m| member_report(m)).collect(),
        member_seconds: Some(reports.iter().map(|r| r.seconds).sum()),
        physical_parameters: physical,
    });
    r
}

fn member_report(r: &TrainReport) -> MemberReport {
    MemberReport {
        best_epoch: r.best_epoch,
        best_val_loss: r.best_val_loss,
        train_loss: r.train_loss,
        val_loss: r.val_loss,
        physical_parameters: r.physical_parameters.clone(),
    }
}
