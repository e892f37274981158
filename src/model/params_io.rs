//! Parameters to and from plain named f64 arrays: the checkpoint and model-file format, the
//! optimizer's view, and (later) the f64 inference path's weights. Values round-trip exactly:
//! f32 → f64 → f32 is lossless.

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor, TensorData};

use crate::error::{Error, Result};

pub use crate::model::NamedArray;

struct Exporter {
    path: Vec<String>,
    out: Vec<NamedArray>,
}

impl ModuleVisitor for Exporter {
    fn enter_module(&mut self, name: &str, _container: &str) {
        self.path.push(name.to_string());
    }
    fn exit_module(&mut self, _name: &str, _container: &str) {
        self.path.pop();
    }
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let t = param.val();
        self.out.push(NamedArray {
            name: self.path.join("."),
            shape: t.dims().to_vec(),
            values: t.into_data().iter::<f64>().collect(),
        });
    }
}

/// Every float parameter of `module` in visiting order (declaration order, deterministic),
/// named `prefix.<path>` (or `prefix` for a lone tensor).
pub fn export_as<M: Module>(prefix: &str, module: &M) -> Vec<NamedArray> {
    let mut v = Exporter {
        path: vec![prefix.to_string()],
        out: vec![],
    };
    module.visit(&mut v);
    v.out
}

struct Importer<'a> {
    arrays: std::slice::Iter<'a, NamedArray>,
    device: Device,
    error: Option<Error>,
}

impl ModuleMapper for Importer<'_> {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, old, _) = param.consume();
        let dims = old.dims();
        let require_grad = old.is_require_grad();
        let value = match self.arrays.next() {
            Some(a)
                if a.shape == dims.to_vec() && a.values.len() == dims.iter().product::<usize>() =>
            {
                Tensor::from_data(TensorData::new(a.values.clone(), dims), &self.device)
            }
            other => {
                self.error.get_or_insert_with(|| {
                    let got = other.map_or("nothing".to_string(), |a| {
                        format!("{} {:?}", a.name, a.shape)
                    });
                    Error::corrupt(
                        "parameters",
                        format!("expected a tensor of shape {dims:?}, found {got}"),
                    )
                });
                old
            }
        };
        Param::initialized(
            id,
            if require_grad {
                value.require_grad()
            } else {
                value
            },
        )
    }
}

/// Loads values into a module built with the same structure; shapes must match one to one.
pub fn import<M: Module>(module: M, arrays: &[NamedArray], device: &Device) -> Result<M> {
    let mut im = Importer {
        arrays: arrays.iter(),
        device: device.clone(),
        error: None,
    };
    let module = module.map(&mut im);
    if let Some(e) = im.error {
        return Err(e);
    }
    if im.arrays.next().is_some() {
        return Err(Error::corrupt(
            "parameters",
            "more arrays than the model has parameters",
        ));
    }
    Ok(module)
}
