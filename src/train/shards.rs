//! Data-parallel training steps: a batch split into shards, each shard's loss and gradient
//! computed on its own thread with its own copy of the parameters, the gradients summed in
//! shard order.
//!
//! Every op of a model, not only the large matrix products, then runs on all the threads a
//! job is given, and the result depends only on the shard count: a run is reproducible for a
//! given count, and a checkpoint records it so that a resumed run splits its batches the
//! same way (and stays bit-equal) whatever threads the resuming process has.

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::tensor::{Gradients, Tensor};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// The gradient of each parameter tensor, flattened, in the module's visiting order (`None`:
/// the loss does not depend on it).
pub type ParamGrads = Vec<Option<Tensor<1>>>;

/// Below this many rows a shard's per-op overhead outweighs what another thread gains, so a
/// batch gets fewer shards (`graybox-lab bench train`, 2 threads against 1: MVF at batch 256, two
/// shards of 128, 83k against 77k samples/s; at batch 128, two shards of 64, 53k against 55k
/// while using a second core).
pub const MIN_SHARD_ROWS: usize = 128;

/// The same for a model without a network: its step is a few hundred scalar columns per row
/// on the tape, a fraction of a millisecond for a small batch, which handing half of it to
/// another thread does not repay (`graybox-lab bench train`, W-B double pendulum: batch 256
/// in two shards 0.28–0.30M samples/s against 0.36–0.37M in one; batch 4096, eight pieces,
/// on two threads 0.56–0.68M against 0.39M on one).
pub const MIN_SHARD_ROWS_WITHOUT_NETWORK: usize = 2048;

/// The fewest rows a shard of `spec`'s model gets: a model with a network, or a robot's on
/// the multibody algorithms (one op of ~40 µs per UR5 row), has per-row work enough for
/// [`MIN_SHARD_ROWS`].
pub fn min_shard_rows(spec: &crate::model::spec::ModelSpec) -> usize {
    if spec.has_network() || spec.multibody().is_some() {
        MIN_SHARD_ROWS
    } else {
        MIN_SHARD_ROWS_WITHOUT_NETWORK
    }
}

/// The most rows one piece of a batch gets on the fused step: a piece's tapes (kept from its
/// forward pass for its backward pass) then stay in a core's cache, where a whole batch's
/// would stream from memory (`graybox-lab bench step`, MVF on one thread: 97k samples/s at
/// 512 rows, 81k at 2048, 82k at 4096).
pub const MAX_FUSED_PIECE_ROWS: usize = 512;

/// The most threads one training may ask for: more is a typo, not a machine.
pub const MAX_THREADS: usize = 256;

/// The cores this process may use: the default thread count of one training.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

/// A pool of `threads` training threads; None for 1 (the caller's thread runs the shards).
pub fn pool(threads: usize) -> Result<Option<std::sync::Arc<rayon::ThreadPool>>> {
    if !(1..=MAX_THREADS).contains(&threads) {
        return Err(Error::invalid(
            "threads",
            format!("must be between 1 and {MAX_THREADS}"),
        ));
    }
    if threads == 1 {
        return Ok(None);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("graybox-train-{i}"))
        .build()
        .map_err(|e| Error::Training(format!("could not start {threads} threads: {e}")))?;
    Ok(Some(std::sync::Arc::new(pool)))
}

/// How many shards a batch of `rows` gets when a run uses `shards` of at least `min_rows`.
pub fn shard_count(shards: usize, rows: usize, min_rows: usize) -> usize {
    shards.min(rows / min_rows).max(1)
}

/// How many pieces a batch of `rows` of `model` is split into when a run uses `shards`: its
/// shards, and more pieces than threads for a large batch (each thread
/// runs its pieces one after another; see [`MAX_FUSED_PIECE_ROWS`]). Like the shard count,
/// it depends on nothing but the run's recorded shards, the batch and the model.
pub fn piece_count(shards: usize, rows: usize, model: &crate::model::Model) -> usize {
    shard_count(shards, rows, min_shard_rows(&model.config.spec))
        .max(rows.div_ceil(MAX_FUSED_PIECE_ROWS))
}

/// `items` in `k` contiguous pieces whose lengths differ by at most one.
pub fn split<T>(items: &[T], k: usize) -> Vec<&[T]> {
    let (base, extra) = (items.len() / k, items.len() % k);
    let mut rest = items;
    (0..k)
        .map(|i| {
            let (head, tail) = rest.split_at(base + usize::from(i < extra));
            rest = tail;
            head
        })
        .collect()
}

/// Runs `f` on every piece, on `pool` when there is one, and returns the results in piece
/// order (so that what is summed afterwards is summed in the same order on any thread).
pub fn map_pieces<T: Sync, R: Send>(
    pieces: &[&[T]],
    pool: Option<&rayon::ThreadPool>,
    f: impl Fn(&[T]) -> R + Sync + Send,
) -> Vec<R> {
    match pool {
        Some(pool) if pieces.len() > 1 => {
            pool.install(|| pieces.par_iter().map(|p| f(p)).collect())
        }
        _ => pieces.iter().map(|p| f(p)).collect(),
    }
}

/// The gradient of every parameter of `module` in `grads`.
pub fn param_grads<M: Module>(module: &M, grads: &Gradients) -> ParamGrads {
    struct Collect<'a> {
        grads: &'a Gradients,
        out: ParamGrads,
    }
    impl ModuleVisitor for Collect<'_> {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            let t = param.val();
            let numel = t.dims().iter().product::<usize>();
            self.out
                .push(t.grad(self.grads).map(|g| g.reshape([numel])));
        }
    }
    let mut c = Collect { grads, out: vec![] };
    module.visit(&mut c);
    c.out
}

/// `loss`'s gradient for every parameter of `module`, all `None` when the loss depends on
/// none of them: Burn's backward pass panics on such a loss, and a template parameter that
/// enters V only as a constant passes `ModelSpec::check_trainable` yet makes one.
pub fn gradients<M: Module>(module: &M, loss: &Tensor<1>) -> ParamGrads {
    if loss.is_tracked() {
        return param_grads(module, &loss.backward());
    }
    struct Untouched(ParamGrads);
    impl ModuleVisitor for Untouched {
        fn visit_float<const D: usize>(&mut self, _: &Param<Tensor<D>>) {
            self.0.push(None);
        }
    }
    let mut none = Untouched(vec![]);
    module.visit(&mut none);
    none.0
}

/// The sum of the shards' gradients, in shard order.
pub fn sum_grads(shards: Vec<ParamGrads>) -> ParamGrads {
    let mut shards = shards.into_iter();
    let first = shards.next().unwrap_or_default();
    shards.fold(first, |acc, g| {
        acc.into_iter()
            .zip(g)
            .map(|(a, b)| match (a, b) {
                (Some(a), Some(b)) => Some(a + b),
                (a, b) => a.or(b),
            })
            .collect()
    })
}

/// The same values as fresh autodiff leaves. Burn merges the graphs of ops that share a
/// tracked input and runs a backward pass under its graph's lock, so shards that read the
/// same parameter tensors would serialize; fresh leaves give each shard its own graph.
pub fn fresh_leaves<M: Module>(module: M) -> M {
    struct Fresh;
    impl ModuleMapper for Fresh {
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            let (id, tensor, _) = param.consume();
            Param::initialized(id, Tensor::from_inner(tensor.inner()).require_grad())
        }
    }
    module.map(&mut Fresh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_covers_items_in_order_with_near_equal_pieces() {
        let items: Vec<usize> = (0..10).collect();
        let pieces = split(&items, 3);
        assert_eq!(
            pieces.iter().map(|p| p.len()).collect::<Vec<_>>(),
            [4, 3, 3]
        );
        assert_eq!(pieces.concat(), items);
        assert_eq!(split(&items, 1), vec![&items[..]]);
    }

    #[test]
    fn small_batches_get_fewer_shards() {
        let min = MIN_SHARD_ROWS;
        assert_eq!(shard_count(2, 8, min), 1);
        assert_eq!(shard_count(2, 255, min), 1);
        assert_eq!(shard_count(2, 256, min), 2);
        assert_eq!(shard_count(4, 4096, min), 4);
        assert_eq!(shard_count(1, 4096, min), 1);
        assert_eq!(shard_count(2, 2048, 2048), 1);
        assert_eq!(shard_count(2, 4096, 2048), 2);
    }

    #[test]
    fn models_without_per_row_work_shard_only_large_batches() {
        use crate::model::spec::ModelSpec;
        use crate::physics::templates::Template;
        let named = |n| ModelSpec::named(n, Some(Template::DoublePendulum)).unwrap();
        for n in ["MVF", "naive", "B", "F", "V", "M"] {
            assert_eq!(min_shard_rows(&named(n)), MIN_SHARD_ROWS, "{n}");
        }
        assert_eq!(
            min_shard_rows(&named("W-B")),
            MIN_SHARD_ROWS_WITHOUT_NETWORK
        );
        // A robot's W-B runs the multibody algorithms: per-row work enough to shard.
        let urdf = include_str!("../../tests/fixtures/urdf/double_pendulum.urdf");
        let robot = crate::physics::urdf::UrdfTemplate::from_urdf(urdf).unwrap();
        let robot = Template::Urdf(std::sync::Arc::new(robot));
        let spec = ModelSpec::named("W-B", Some(robot)).unwrap();
        assert_eq!(min_shard_rows(&spec), MIN_SHARD_ROWS);
    }
}
