//! Branch-free elementwise math (exp, tanh and tanh's derivative) over slices, compiled for
//! the widest vector unit the CPU has: libm's scalar calls (one per element) were the largest
//! single cost of both the f64 evaluator (`infer/activations.rs`) and training (the tape's network node, `physics/tape/mlp.rs`).

/// Defines `pub fn $name` calling an `#[inline(always)]` kernel compiled for the widest vector
/// unit the CPU has (AVX-512, else AVX2 + FMA, else the baseline), chosen at run time: the
/// binary stays portable and the elementwise loops still get full-width vectors.
macro_rules! multiversion {
    ($(#[$doc:meta])* fn $name:ident($($a:ident: $t:ty),*) => $kernel:ident) => {
        $(#[$doc])*
        pub fn $name($($a: $t),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f")]
                fn avx512($($a: $t),*) {
                    $kernel::<true>($($a),*)
                }
                #[target_feature(enable = "avx2,fma")]
                fn avx2($($a: $t),*) {
                    $kernel::<true>($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F.
                    return unsafe { avx512($($a),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU has AVX2 and FMA.
                    return unsafe { avx2($($a),*) };
                }
            }
            $kernel::<false>($($a),*)
        }
    };
}

pub(crate) use multiversion;

/// a·b + c, fused where the kernel is compiled with FMA (a libm call otherwise, hence the flag).
#[inline(always)]
pub fn mad<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// a·b + c in f32 (see [`mad`]).
#[inline(always)]
pub fn mad_f32<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

multiversion! {
    /// tanh(z) = 1 − 2 / (e^{2z} + 1) over a slice, with a branch-free exp that vectorises
    /// (libm's tanh, one call per unit, was most of a Predict's time). Absolute error ≲ 1e-16.
    fn tanh_in_place(z: &mut [f64]) => tanh_kernel
}

#[inline(always)]
pub fn tanh_kernel<const FMA: bool>(z: &mut [f64]) {
    for v in z.iter_mut() {
        let e = exp_approx::<FMA>(2.0 * v.clamp(-20.0, 20.0));
        *v = 1.0 - 2.0 / (e + 1.0);
    }
}

/// e^x for |x| ≤ 700: x = k ln 2 + r with |r| ≤ ln2/2, e^r by its Taylor series to r¹³
/// (remainder < 5e-18 relative; Estrin's scheme keeps the dependency chain short), 2^k
/// assembled in the exponent bits. No branches or libm calls, so a loop over it vectorises.
#[inline(always)]
pub fn exp_approx<const FMA: bool>(x: f64) -> f64 {
    const MAGIC: f64 = 6755399441055744.0; // 1.5·2^52: adding it rounds to an integer
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    const C: [f64; 14] = [
        1.0,
        1.0,
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    let t = mad::<FMA>(x, std::f64::consts::LOG2_E, MAGIC);
    let k = t - MAGIC;
    let r = mad::<FMA>(-k, LN2_LO, mad::<FMA>(-k, LN2_HI, x));
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let pair = |i: usize| mad::<FMA>(C[i + 1], r, C[i]);
    let p0 = mad::<FMA>(pair(2), r2, pair(0));
    let p1 = mad::<FMA>(pair(6), r2, pair(4));
    let p2 = mad::<FMA>(pair(10), r2, pair(8));
    let p3 = pair(12);
    let p = mad::<FMA>(mad::<FMA>(p3, r4, p2), r8, mad::<FMA>(p1, r4, p0));
    // t's low mantissa bits hold k (two's complement); 2^k has biased exponent k + 1023.
    let bits = t.to_bits().wrapping_sub(MAGIC.to_bits()).wrapping_add(1023) << 52;
    p * f64::from_bits(bits)
}

multiversion! {
    /// tanh over an f32 slice (see [`tanh_in_place`]); absolute error ≲ 2e-7.
    fn tanh_in_place_f32(z: &mut [f32]) => tanh_kernel_f32
}

#[inline(always)]
fn tanh_kernel_f32<const FMA: bool>(z: &mut [f32]) {
    for v in z.iter_mut() {
        // |z| ≥ 9: tanh rounds to ±1 in f32, and e^{2z} stays finite.
        let e = exp_approx_f32::<FMA>(2.0 * v.clamp(-9.0, 9.0));
        *v = 1.0 - 2.0 / (e + 1.0);
    }
}

/// e^x in f32 for |x| ≤ 80 (see [`exp_approx`]): Taylor to r⁷, remainder < 6e-9 relative,
/// below f32's rounding.
#[inline(always)]
pub fn exp_approx_f32<const FMA: bool>(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5·2^23: adding it rounds to an integer
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    const C: [f32; 8] = [
        1.0,
        1.0,
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
    ];
    let t = mad_f32::<FMA>(x, std::f32::consts::LOG2_E, MAGIC);
    let k = t - MAGIC;
    let r = mad_f32::<FMA>(-k, LN2_LO, mad_f32::<FMA>(-k, LN2_HI, x));
    let r2 = r * r;
    let r4 = r2 * r2;
    let pair = |i: usize| mad_f32::<FMA>(C[i + 1], r, C[i]);
    let p = mad_f32::<FMA>(
        mad_f32::<FMA>(pair(6), r2, pair(4)),
        r4,
        mad_f32::<FMA>(pair(2), r2, pair(0)),
    );
    // t's low mantissa bits hold k (two's complement); 2^k has biased exponent k + 127.
    let bits = t.to_bits().wrapping_sub(MAGIC.to_bits()).wrapping_add(127) << 23;
    p * f32::from_bits(bits)
}

multiversion! {
    /// g ← g (1 − y²): tanh's backward from its output, one pass.
    fn tanh_grad_in_place(g: &mut [f64], y: &[f64]) => tanh_grad_kernel
}

#[inline(always)]
fn tanh_grad_kernel<const FMA: bool>(g: &mut [f64], y: &[f64]) {
    for (g, &y) in g.iter_mut().zip(y) {
        *g *= 1.0 - y * y;
    }
}

multiversion! {
    /// g ← g (1 − y²) in f32.
    fn tanh_grad_in_place_f32(g: &mut [f32], y: &[f32]) => tanh_grad_kernel_f32
}

#[inline(always)]
fn tanh_grad_kernel_f32<const FMA: bool>(g: &mut [f32], y: &[f32]) {
    for (g, &y) in g.iter_mut().zip(y) {
        *g *= 1.0 - y * y;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_and_tanh_match_libm() {
        // Relative 1e-15 (≈ 4 ulp) for exp, absolute 1e-15 for tanh: far below the 1e-9
        // agreement the evaluator promises, and tight enough to catch a wrong coefficient
        // (dropping the r¹³ term alone gives 1e-14). Both the fused and the unfused variant.
        let mut worst_exp = 0.0f64;
        let mut z: Vec<f64> = (-4000..=4000).map(|i| i as f64 * 0.01).collect();
        for &x in &z {
            let x = x * 10.0;
            for e in [exp_approx::<false>(x), exp_approx::<true>(x)] {
                worst_exp = worst_exp.max((e - x.exp()).abs() / x.exp());
            }
        }
        assert!(worst_exp < 1e-15, "exp relative error {worst_exp:e}");
        let reference: Vec<f64> = z.iter().map(|v| v.tanh()).collect();
        tanh_in_place(&mut z);
        let worst = z
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-15, "tanh absolute error {worst:e}");
    }

    #[test]
    fn f32_exp_and_tanh_match_libm() {
        // exp: 4 ulp relative (f32 ε = 1.2e-7). tanh: 2.5e-7 absolute, two ulp of 1 (the form
        // 1 − 2/(e + 1) rounds near 1); dropping the r⁷ term gives 3e-6 relative in exp.
        let mut worst_exp = 0.0f64;
        for i in -8000..=8000 {
            let x = i as f32 * 0.01;
            for e in [exp_approx_f32::<false>(x), exp_approx_f32::<true>(x)] {
                let want = f64::from(x).exp();
                worst_exp = worst_exp.max((f64::from(e) - want).abs() / want);
            }
        }
        assert!(worst_exp < 5e-7, "exp relative error {worst_exp:e}");
        let mut z: Vec<f32> = (-2000..=2000).map(|i| i as f32 * 0.01).collect();
        let reference: Vec<f64> = z.iter().map(|&v| f64::from(v).tanh()).collect();
        tanh_in_place_f32(&mut z);
        let worst = z
            .iter()
            .zip(&reference)
            .map(|(&a, b)| (f64::from(a) - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 2.5e-7, "tanh absolute error {worst:e}");
    }

    #[test]
    fn tanh_grad_is_one_minus_y_squared_times_g() {
        let y = [0.0, 0.5, -0.9, 1.0];
        let mut g = [2.0, 2.0, -1.0, 3.0];
        tanh_grad_in_place(&mut g, &y);
        assert_eq!(g, [2.0, 1.5, -(1.0 - 0.9 * 0.9), 0.0]);
        let mut g32 = [2.0f32, 2.0];
        tanh_grad_in_place_f32(&mut g32, &[0.0, 0.5]);
        assert_eq!(g32, [2.0, 1.5]);
    }
}
