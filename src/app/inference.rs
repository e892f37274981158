//! Inference on trained models for controllers (the gRPC adapter calls these): one-step
//! prediction, rollouts, linearizations and TVLQR, in f64 on the evaluator, off the async
//! executor. Loaded models stay in a cache until deleted.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use super::App;
use crate::control::linalg::Mat;
use crate::error::{Error, Result};
use crate::infer::{Evaluator, finite_rows};
use crate::train::artifact::ModelFile;

#[derive(Default)]
pub struct ModelCache {
    loaded: Mutex<HashMap<String, Arc<Evaluator>>>,
}

impl ModelCache {
    fn get(&self, model_id: &str) -> Option<Arc<Evaluator>> {
        self.loaded
            .lock()
            .expect("model cache lock")
            .get(model_id)
            .cloned()
    }

    fn insert(&self, model_id: &str, eval: Arc<Evaluator>) {
        self.loaded
            .lock()
            .expect("model cache lock")
            .insert(model_id.to_string(), eval);
    }

    pub fn evict(&self, model_id: &str) {
        self.loaded
            .lock()
            .expect("model cache lock")
            .remove(model_id);
    }
}

/// A batch of rows: `rows` × `width`, row-major.
pub struct Rows<'a> {
    pub data: &'a [f64],
    pub rows: usize,
    pub width: usize,
}

/// Checks an array's shape and values; `field` names it in errors.
pub fn rows<'a>(field: &str, shape: &[u64], data: &'a [f64], width: usize) -> Result<Rows<'a>> {
    let [r, w] = shape else {
        return Err(Error::invalid(
            field,
            format!("shape must be [rows, {width}], got {shape:?}"),
        ));
    };
    let (r, w) = (*r as usize, *w as usize);
    if w != width || r == 0 || data.len() != r * w {
        return Err(Error::invalid(
            field,
            format!(
                "expected [rows ≥ 1, {width}] with rows·{width} values, got shape {shape:?} and {} values",
                data.len()
            ),
        ));
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid(
            field,
            format!("row {} has a non-finite value", i / width),
        ));
    }
    Ok(Rows {
        data,
        rows: r,
        width,
    })
}

fn square(field: &str, shape: &[u64], data: &[f64], dim: usize) -> Result<Mat> {
    let r = rows(field, shape, data, dim)?;
    if r.rows != dim {
        return Err(Error::invalid(field, format!("must be {dim}×{dim}")));
    }
    Ok(Mat::new(dim, dim, data.to_vec()))
}

/// A batch of states `[B, 2n]` and inputs `[B, m]` with the same B.
fn check_batch(eval: &Evaluator, x: (&[f64], &[u64]), u: (&[f64], &[u64])) -> Result<()> {
    let xr = rows("x", x.1, x.0, 2 * eval.config.n)?.rows;
    let ur = rows("u", u.1, u.0, eval.config.m)?.rows;
    if xr != ur {
        return Err(Error::invalid("u", format!("has {ur} rows but x has {xr}")));
    }
    Ok(())
}

/// Runs CPU-bound work on the blocking pool so the async executor stays responsive.
async fn blocking<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> Result<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| Error::Training(format!("inference task failed: {e}")))
}

/// Up to this many states a Predict runs on the executor thread itself (≈ 15–20 µs a state;
/// one Linearize, also inline, ≈ 60 µs): a hop to the blocking pool and back costs more than
/// that (measured: a one-state Predict round trip went from ~250 to ~190 µs p50 inline, and
/// 64 concurrent clients from 10k to 16k requests/s).
const INLINE_ROWS: usize = 4;

/// `f` inline when the work is small (see [`INLINE_ROWS`]), else on the blocking pool.
async fn compute<T: Send + 'static>(
    small: bool,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<T> {
    if small { Ok(f()) } else { blocking(f).await }
}

impl App {
    /// The evaluator of a model (or of the model a succeeded job produced), loaded once. A
    /// cached model answers without touching the database: a control loop calls this at
    /// hundreds of hertz, and a SQLite round trip was most of a one-state Predict.
    pub async fn evaluator(&self, id: &str) -> Result<Arc<Evaluator>> {
        if let Some(e) = self.models.get(id) {
            return Ok(e);
        }
        let row = self.resolve_model(id).await?;
        if let Some(e) = self.models.get(&row.id) {
            return Ok(e);
        }
        let bytes = self.model_file(&row.id).await?;
        let eval = Arc::new(
            blocking(move || Evaluator::from_file(&ModelFile::from_bytes(&bytes)?)).await??,
        );
        self.models.insert(&row.id, eval.clone());
        Ok(eval)
    }

    pub async fn delete_model(&self, id: &str) -> Result<()> {
        self.store.delete_model(id).await?;
        self.models.evict(id);
        Ok(())
    }

    /// x' (and q̈ when asked) for a batch.
    pub async fn predict(
        &self,
        id: &str,
        x: Vec<f64>,
        x_shape: Vec<u64>,
        u: Vec<f64>,
        u_shape: Vec<u64>,
        want_accel: bool,
    ) -> Result<(Vec<f64>, Option<Vec<f64>>)> {
        let eval = self.evaluator(id).await?;
        check_batch(&eval, (&x, &x_shape), (&u, &u_shape))?;
        let small = x.len() <= INLINE_ROWS * 2 * eval.config.n;
        let (next, acc) = compute(small, move || eval.predict(&x, &u, want_accel)).await?;
        finite_rows("x", "next state", &next, x_shape[1] as usize)?;
        Ok((next, acc))
    }

    /// A and B for a batch, row-major `[B, 2n, 2n]` and `[B, 2n, m]`.
    pub async fn linearize(
        &self,
        id: &str,
        x: Vec<f64>,
        x_shape: Vec<u64>,
        u: Vec<f64>,
        u_shape: Vec<u64>,
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let eval = self.evaluator(id).await?;
        check_batch(&eval, (&x, &x_shape), (&u, &u_shape))?;
        let nx = x_shape[1] as usize;
        let (a, b) = compute(x.len() == nx, move || eval.linearize_batch(&x, &u)).await?;
        finite_rows("x", "linearization", &a, nx * nx)?;
        finite_rows("x", "linearization", &b, nx * u_shape[1] as usize)?;
        Ok((a, b))
    }

    /// TVLQR gains along a nominal (x̄, ū); defects are ignored.
    #[allow(clippy::too_many_arguments)]
    pub async fn tvlqr(
        &self,
        id: &str,
        xbar: (Vec<f64>, Vec<u64>),
        ubar: (Vec<f64>, Vec<u64>),
        q: (Vec<f64>, Vec<u64>),
        r: (Vec<f64>, Vec<u64>),
        qf: (Vec<f64>, Vec<u64>),
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let eval = self.evaluator(id).await?;
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        let t_x = rows("x_bar", &xbar.1, &xbar.0, nx)?.rows;
        let t_u = rows("u_bar", &ubar.1, &ubar.0, m)?.rows;
        if t_x != t_u + 1 {
            return Err(Error::invalid(
                "x_bar",
                format!(
                    "needs T+1 = {} states for T = {t_u} inputs, got {t_x}",
                    t_u + 1
                ),
            ));
        }
        if t_u > self.settings.max_rollout_steps {
            return Err(Error::ResourceExhausted(format!(
                "horizon {t_u} is over the limit of {}",
                self.settings.max_rollout_steps
            )));
        }
        let (qm, rm, qfm) = (
            square("Q", &q.1, &q.0, nx)?,
            square("R", &r.1, &r.0, m)?,
            square("Qf", &qf.1, &qf.0, nx)?,
        );
        blocking(move || {
            let g = eval.tvlqr(&xbar.0, &ubar.0, &qm, &rm, &qfm)?;
            Ok((
                g.k.into_iter().flat_map(|k| k.data).collect(),
                g.s.into_iter().flat_map(|s| s.data).collect(),
            ))
        })
        .await?
    }
}
