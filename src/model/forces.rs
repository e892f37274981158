//! Generalized forces F(q, q̇, u) for the Burn path: the affine forms B u + η ∘ q̇ with B from
//! a network or constant. (The general MLP is a plain forward pass; the template's F is
//! generic code in `templates`.)

use burn::tensor::Tensor;

/// B u + η ∘ q̇ with B given flat per sample `[batch, n·m]` or shared `[1, n·m]`.
pub fn affine(b_flat: Tensor<2>, u: Tensor<2>, eta: Tensor<2>, qd: Tensor<2>) -> Tensor<2> {
    let [bb, nm] = b_flat.dims();
    let [batch, m] = u.dims();
    let n = nm / m;
    let bu = if bb == 1 {
        // [batch, m] · Bᵀ [m, n]
        u.matmul(b_flat.reshape([n, m]).transpose())
    } else {
        // Σ_j B_ij u_j per sample
        (b_flat.reshape([batch, n, m]) * u.unsqueeze_dim::<3>(1))
            .sum_dim(2)
            .reshape([batch, n])
    };
    bu + qd * eta
}
