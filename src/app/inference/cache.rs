//! Loaded models, and the deletions they must not outlive.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};

use crate::infer::Evaluator;

/// How often a process checks that its cached models still exist: the documented bound on
/// how long a model deleted through another process on the same database is still served.
pub const CACHE_SWEEP: std::time::Duration = std::time::Duration::from_millis(500);

/// Loaded models by id, and the ids deleted while this process ran: a load that raced a
/// delete must not put the deleted model back (model ids are never reused, so the set only
/// grows by one id per deletion).
#[derive(Default)]
pub struct ModelCache {
    inner: Mutex<CacheState>,
}

#[derive(Default)]
struct CacheState {
    loaded: HashMap<String, Arc<Evaluator>>,
    deleted: HashSet<String>,
}

impl ModelCache {
    fn lock(&self) -> std::sync::MutexGuard<'_, CacheState> {
        self.inner.lock().expect("model cache lock")
    }

    pub(super) fn get(&self, model_id: &str) -> Option<Arc<Evaluator>> {
        self.lock().loaded.get(model_id).cloned()
    }

    /// False when the model was deleted meanwhile.
    pub(super) fn insert(&self, model_id: &str, eval: Arc<Evaluator>) -> bool {
        let mut c = self.lock();
        if c.deleted.contains(model_id) {
            return false;
        }
        c.loaded.insert(model_id.to_string(), eval);
        true
    }

    pub fn evict(&self, model_id: &str) {
        let mut c = self.lock();
        c.loaded.remove(model_id);
        c.deleted.insert(model_id.to_string());
    }

    pub fn cached_ids(&self) -> Vec<String> {
        self.lock().loaded.keys().cloned().collect()
    }
}
