//! The W-B ensemble's bootstrap error bars: each physical parameter's members' mean and σ
//! (the file's `ensemble.physical_parameters`) against its true value, and the same for the
//! combinations of them that the data identifies (from each member's values).

use std::collections::BTreeMap;

use serde::Serialize;

use super::ErrorBarSettings;
use graybox::error::{Error, Result};
use graybox::model::file::ModelFile;
use graybox::model::report::Spread;
use graybox::physics::templates::Template;

/// A parameter's start relative to its true value: alternately 20% above and below, in the
/// template's order.
pub fn init_factors(t: &Template) -> Vec<(String, f64)> {
    (t.params().iter().enumerate())
        .map(|(i, p)| (p.name.to_string(), if i % 2 == 0 { 1.2 } else { 0.8 }))
        .collect()
}

/// The starting values: the true ones times the settings' factors.
pub fn init(t: &Template, s: &ErrorBarSettings) -> Vec<(String, f64)> {
    let truth = t.defaults();
    (s.init_factors.iter())
        .map(|(name, f)| {
            let i = t
                .index_of(name)
                .expect("the factors name the template's parameters");
            (name.clone(), truth[i] * f)
        })
        .collect()
}

/// One row: a parameter or an identifiable combination.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub name: String,
    pub truth: f64,
    pub init: f64,
    pub mean: f64,
    pub std: f64,
    pub error: f64,
    /// |mean − truth| / σ (∞ for σ = 0 and an error).
    pub z: f64,
    pub inside_3sigma: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct ErrorBars {
    pub parameters: Vec<Row>,
    pub combinations: Vec<Row>,
    /// Each member's values, by parameter.
    pub members: Vec<BTreeMap<String, f64>>,
}

pub fn table(file: &ModelFile, s: &ErrorBarSettings) -> Result<ErrorBars> {
    let t = Template::DoublePendulum;
    let missing = || Error::Internal("the W-B file has no ensemble report".into());
    let report = file.report.as_ref().ok_or_else(missing)?;
    let ens = report.ensemble.as_ref().ok_or_else(missing)?;
    let truth = t.defaults();
    let init = init(&t, s);
    let start = |name: &str| {
        init.iter()
            .find(|(n, _)| n == name)
            .map_or(f64::NAN, |p| p.1)
    };
    let parameters = (ens.physical_parameters.iter())
        .map(|(name, spread)| {
            let i = t.index_of(name).expect("a template parameter");
            row(name, truth[i], start(name), *spread)
        })
        .collect();
    let members: Vec<BTreeMap<String, f64>> = (ens.members.iter())
        .map(|m| m.physical_parameters.clone())
        .collect();
    let value = |values: &dyn Fn(&str) -> f64, c: &graybox::physics::templates::Combination| {
        (c.eval)(&|name: &str| values(name))
    };
    let combinations = (t.combinations().iter())
        .map(|c| {
            let each: Vec<f64> = (members.iter())
                .map(|m| value(&|n| m.get(n).copied().unwrap_or(f64::NAN), c))
                .collect();
            let true_value = value(&|n| t.index_of(n).map_or(f64::NAN, |i| truth[i]), c);
            let start_value = value(&start, c);
            row(c.name, true_value, start_value, Spread::of(&each))
        })
        .collect();
    Ok(ErrorBars {
        parameters,
        combinations,
        members,
    })
}

fn row(name: &str, truth: f64, init: f64, s: Spread) -> Row {
    let error = (s.mean - truth).abs();
    let z = if s.std > 0.0 {
        error / s.std
    } else if error == 0.0 {
        0.0
    } else {
        f64::INFINITY
    };
    Row {
        name: name.to_string(),
        truth,
        init,
        mean: s.mean,
        std: s.std,
        error,
        z,
        inside_3sigma: z <= 3.0,
    }
}
