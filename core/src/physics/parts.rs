//! The form each part of the manipulator equation takes in a model: a network (its hidden
//! widths), a learned constant, or the template's analytic form with an optional residual
//! network. The model's spec (`model::spec`) combines one of each; the assembly reads them.

use serde::{Deserialize, Serialize};

pub const STRUCTURED_HIDDEN: [usize; 3] = [32, 32, 32];

pub fn structured_hidden() -> Vec<usize> {
    STRUCTURED_HIDDEN.to_vec()
}

/// M(q).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MassSpec {
    /// Cholesky MLP: q → the n(n+1)/2 entries of L, diagonal through softplus + ε.
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    /// The template's analytic M(q) with trainable physical parameters.
    Template,
    /// A learned constant SPD matrix.
    Constant,
}

/// A network added to a white-box part (F = F_t + F_net(q, q̇, u), V = V_t + V_net(q)); its
/// last layer starts at zero, so training starts exactly at the physics model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Residual {
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
}

/// V(q).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PotentialSpec {
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    Template {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        residual: Option<Residual>,
    },
    Zero,
    /// ½ qᵀKq with K symmetric and learned.
    Quadratic,
}

/// F(q, q̇, u).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ForceSpec {
    /// General MLP [q, q̇, u] → Rⁿ.
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    /// B_θ(q) u + η ∘ q̇ with B_θ an MLP q → n×m and η learned.
    ControlAffine {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    /// Constant learned B and diagonal damping: B u + η ∘ q̇.
    ConstantAffine,
    /// Passive by construction: B_θ(q) u − D_θ(q, q̇) q̇ with B_θ an MLP q → n×m and D
    /// symmetric positive definite from an MLP [q, q̇] → the n(n+1)/2 entries of a factor
    /// (docs/energy.md#passive-forces): the unforced force only ever takes energy out.
    Passive {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    Template {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        residual: Option<Residual>,
    },
}

impl Residual {
    fn hidden(r: &Option<Residual>) -> Option<&[usize]> {
        r.as_ref().map(|Residual::Mlp { hidden }| hidden.as_slice())
    }
}

impl PotentialSpec {
    /// The template's V without a residual.
    pub const TEMPLATE: Self = PotentialSpec::Template { residual: None };

    /// The hidden widths of the potential's network q → V: a network potential's, or a
    /// template potential's residual.
    pub fn network(&self) -> Option<&[usize]> {
        match self {
            PotentialSpec::Mlp { hidden } => Some(hidden),
            PotentialSpec::Template { residual } => Residual::hidden(residual),
            PotentialSpec::Zero | PotentialSpec::Quadratic => None,
        }
    }

    /// Whether the network is a residual on the template's V (its last layer starts at zero).
    pub fn is_residual(&self) -> bool {
        matches!(self, PotentialSpec::Template { residual: Some(_) })
    }
}

impl ForceSpec {
    /// The template's F without a residual.
    pub const TEMPLATE: Self = ForceSpec::Template { residual: None };

    /// The hidden widths of the general force network [q, q̇, u] → F: an MLP force's, or a
    /// template force's residual (the control-affine B network is another shape).
    pub fn network(&self) -> Option<&[usize]> {
        match self {
            ForceSpec::Mlp { hidden } => Some(hidden),
            ForceSpec::Template { residual } => Residual::hidden(residual),
            ForceSpec::ControlAffine { .. }
            | ForceSpec::ConstantAffine
            | ForceSpec::Passive { .. } => None,
        }
    }

    /// Whether the network is a residual on the template's F (its last layer starts at zero).
    pub fn is_residual(&self) -> bool {
        matches!(self, ForceSpec::Template { residual: Some(_) })
    }
}
