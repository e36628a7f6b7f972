//! Cardinal B-splines `M_n` (EPBDLP95 section 3): the weights of one particle on the grid
//! points of one axis, with their first and second derivatives, and the moduli `|b(m)|²`
//! of the influence function.
//!
//! `M_2(x) = 1 − |x − 1|` on `[0, 2]`; `M_n(x) = x/(n−1) M_{n−1}(x) + (n−x)/(n−1)
//! M_{n−1}(x−1)` (EPBDLP95 eq. (4.1)); `M_n′(x) = M_{n−1}(x) − M_{n−1}(x−1)` (eq. (4.2)) and
//! so `M_n″(x) = M_{n−2}(x) − 2M_{n−2}(x−1) + M_{n−2}(x−2)`.
//!
//! A particle at scaled coordinate `u = K s` (`s` fractional) with `u = i₀ + w`, `0 ≤ w < 1`,
//! touches the grid points `i₀ − k`, `k = 0 … n−1`, with weight `M_n(w + k)`.

use super::float::MeshFloat;

/// The largest order the arrays hold.
pub const MAX_ORDER: usize = 6;

/// Weights `M_n(w + k)`, `M_n′(w + k)` and `M_n″(w + k)` for `k < order`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Weights<T> {
    pub value: [T; MAX_ORDER],
    pub first: [T; MAX_ORDER],
    pub second: [T; MAX_ORDER],
}

/// `M_p(w + k)` for `k < p` from `M_{p−1}(w + k)` (zero from `p − 1` on): eq. (4.1) with
/// the two ends, where one of the two terms vanishes, apart.
#[inline(always)]
fn raise<T: MeshFloat>(previous: &[T; MAX_ORDER], p: usize, w: T) -> [T; MAX_ORDER] {
    let mut next = [T::zero(); MAX_ORDER];
    let scale = T::of(1.0 / (p - 1) as f64);
    let top = T::of(p as f64);
    next[0] = scale * w * previous[0];
    for k in 1..p - 1 {
        let x = w + T::of(k as f64);
        next[k] = scale * (x * previous[k] + (top - x) * previous[k - 1]);
    }
    next[p - 1] = scale * (top - (w + T::of((p - 1) as f64))) * previous[p - 2];
    next
}

/// `a(k) − a(k − 1)` for `k < order` (`a(−1) = 0`; `a` is zero past its order).
#[inline(always)]
fn difference<T: MeshFloat>(a: &[T; MAX_ORDER], order: usize) -> [T; MAX_ORDER] {
    let mut out = [T::zero(); MAX_ORDER];
    out[0] = a[0];
    for k in 1..order {
        out[k] = a[k] - a[k - 1];
    }
    out
}

/// The weights of order `order` (3 ≤ order ≤ [`MAX_ORDER`]) at offset `w ∈ [0, 1)`; the
/// second derivatives only with `second` (else zero): only Hessian-vector products use them.
/// In `T`'s arithmetic throughout.
pub fn weights<T: MeshFloat>(order: usize, w: T, second: bool) -> Weights<T> {
    match order {
        3 => weights_of::<T, 3>(w, second),
        4 => weights_of::<T, 4>(w, second),
        5 => weights_of::<T, 5>(w, second),
        _ => weights_of::<T, 6>(w, second),
    }
}

/// [`weights`] for a fixed order (its loops unrolled).
#[inline(always)]
pub fn weights_of<T: MeshFloat, const ORDER: usize>(w: T, second: bool) -> Weights<T> {
    let order = ORDER;
    // M_1 is the box on [0, 1): M_1(w) = 1; M_2(w) = w, M_2(w + 1) = 1 − w.
    let mut lower2 = [T::zero(); MAX_ORDER];
    lower2[0] = T::one();
    let mut lower1 = [T::zero(); MAX_ORDER];
    lower1[0] = w;
    lower1[1] = T::one() - w;
    let mut m = raise(&lower1, 3, w);
    for p in 4..=order {
        lower2 = lower1;
        lower1 = m;
        m = raise(&m, p, w);
    }
    // Now m = M_n, lower1 = M_{n−1}, lower2 = M_{n−2}: eq. (4.2) and its derivative.
    let first = difference(&lower1, order);
    Weights {
        value: m,
        first,
        second: if second {
            let d = difference(&lower2, order - 1);
            difference(&d, order)
        } else {
            [T::zero(); MAX_ORDER]
        },
    }
}

/// [`weights_of`] of `B` offsets side by side: `value[k][b]`, `first[k][b]` and (with
/// `second`, else left as they are) `second[k][b]` are `M_N(w_b + k)` and its derivatives.
/// The same operations in the same order per lane as [`weights_of`], so the same bits;
/// written lane-innermost so that the loops vectorise over the offsets.
#[inline(always)]
pub fn weights_batch<T: MeshFloat, const N: usize, const B: usize>(
    w: &[T; B],
    second: bool,
    out: &mut WeightsBatch<T, B>,
) {
    let mut lower2 = [[T::zero(); B]; MAX_ORDER];
    lower2[0] = [T::one(); B];
    let mut lower1 = [[T::zero(); B]; MAX_ORDER];
    lower1[0] = *w;
    lower1[1] = std::array::from_fn(|b| T::one() - w[b]);
    let mut m = raise_batch(&lower1, 3, w);
    for p in 4..=N {
        lower2 = lower1;
        lower1 = m;
        m = raise_batch(&m, p, w);
    }
    out.value[..N].copy_from_slice(&m[..N]);
    difference_batch(&lower1, N, &mut out.first);
    if second {
        let mut d = [[T::zero(); B]; MAX_ORDER];
        difference_batch(&lower2, N - 1, &mut d);
        difference_batch(&d, N, &mut out.second);
    }
}

/// The weights of [`weights_batch`], `[k][b]`.
pub struct WeightsBatch<T, const B: usize> {
    pub value: [[T; B]; MAX_ORDER],
    pub first: [[T; B]; MAX_ORDER],
    pub second: [[T; B]; MAX_ORDER],
}

impl<T: MeshFloat, const B: usize> WeightsBatch<T, B> {
    pub fn new() -> Self {
        let zero = [[T::zero(); B]; MAX_ORDER];
        WeightsBatch {
            value: zero,
            first: zero,
            second: zero,
        }
    }
}

/// [`raise`] lane by lane.
#[inline(always)]
fn raise_batch<T: MeshFloat, const B: usize>(
    previous: &[[T; B]; MAX_ORDER],
    p: usize,
    w: &[T; B],
) -> [[T; B]; MAX_ORDER] {
    let mut next = [[T::zero(); B]; MAX_ORDER];
    let scale = T::of(1.0 / (p - 1) as f64);
    let top = T::of(p as f64);
    for b in 0..B {
        next[0][b] = scale * w[b] * previous[0][b];
    }
    for k in 1..p - 1 {
        let shift = T::of(k as f64);
        for b in 0..B {
            let x = w[b] + shift;
            next[k][b] = scale * (x * previous[k][b] + (top - x) * previous[k - 1][b]);
        }
    }
    let last = T::of((p - 1) as f64);
    for b in 0..B {
        next[p - 1][b] = scale * (top - (w[b] + last)) * previous[p - 2][b];
    }
    next
}

/// [`difference`] lane by lane, into `out`.
#[inline(always)]
fn difference_batch<T: MeshFloat, const B: usize>(
    a: &[[T; B]; MAX_ORDER],
    order: usize,
    out: &mut [[T; B]; MAX_ORDER],
) {
    out[0] = a[0];
    for k in 1..order {
        for b in 0..B {
            out[k][b] = a[k][b] - a[k - 1][b];
        }
    }
}

/// The denominators `|Σ_{k=0}^{n−2} M_n(k+1) exp(2πi mk/K)|²` of `|b(m)|²` (EPBDLP95 eq.
/// (4.4)) for `m = 0 … K−1`. For odd orders they vanish at `m = K/2`; a value below 1e-7
/// is replaced by the mean of its neighbours, as OpenMM's and GROMACS's PME do (the
/// influence function stays finite, and the results match theirs).
pub fn moduli(order: usize, size: usize) -> Vec<f64> {
    let at_integers = weights(order, 0.0f64, false).value;
    // M_n(k + 1) for k = 0 … n−2 is value[k + 1].
    let mut out: Vec<f64> = (0..size)
        .map(|m| {
            let (mut re, mut im) = (0.0, 0.0);
            for k in 0..order - 1 {
                let arg = 2.0 * std::f64::consts::PI * (m * k) as f64 / size as f64;
                re += at_integers[k + 1] * arg.cos();
                im += at_integers[k + 1] * arg.sin();
            }
            re * re + im * im
        })
        .collect();
    for m in 0..size {
        if out[m] < 1e-7 {
            out[m] = 0.5 * (out[(m + size - 1) % size] + out[(m + 1) % size]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `M_n` by its explicit formula `1/(n−1)! Σ_j (−1)^j C(n, j) (x − j)₊^{n−1}`.
    fn explicit(n: usize, x: f64) -> f64 {
        let mut sum = 0.0;
        let mut binomial = 1.0;
        let mut factorial = 1.0;
        for j in 1..n {
            factorial *= j as f64;
        }
        for j in 0..=n {
            if j > 0 {
                binomial *= (n - j + 1) as f64 / j as f64;
            }
            let t = x - j as f64;
            if t > 0.0 {
                sum += if j % 2 == 0 { 1.0 } else { -1.0 } * binomial * t.powi(n as i32 - 1);
            }
        }
        sum / factorial
    }

    #[test]
    fn batches_give_the_bits_of_single_weights() {
        fn check<T: MeshFloat, const N: usize>() {
            let w: [T; 16] = std::array::from_fn(|b| T::of(b as f64 / 16.0 + 0.013));
            let mut batch = WeightsBatch::<T, 16>::new();
            weights_batch::<T, N, 16>(&w, true, &mut batch);
            for (b, &w) in w.iter().enumerate() {
                let one = weights_of::<T, N>(w, true);
                for k in 0..N {
                    assert!(
                        batch.value[k][b] == one.value[k],
                        "order {N} lane {b} k {k}"
                    );
                    assert!(
                        batch.first[k][b] == one.first[k],
                        "order {N} lane {b} k {k}"
                    );
                    assert!(
                        batch.second[k][b] == one.second[k],
                        "order {N} lane {b} k {k}"
                    );
                }
            }
        }
        check::<f64, 4>();
        check::<f64, 5>();
        check::<f64, 6>();
        check::<f32, 4>();
        check::<f32, 5>();
        check::<f32, 6>();
    }

    #[test]
    fn weights_match_the_explicit_spline_and_its_derivatives() {
        for order in 4..=MAX_ORDER {
            // Off the knots (w = 0), where a central second difference of the cubic
            // spline's M″ (a kink) is only O(h).
            for w in [0.13, 0.5, 0.77, 0.999] {
                let got = weights::<f64>(order, w, true);
                let total: f64 = got.value[..order].iter().sum();
                // Partition of unity, to round-off.
                assert!((total - 1.0).abs() < 1e-14);
                for k in 0..order {
                    let x = w + k as f64;
                    let h = 1e-4;
                    let d1 = (explicit(order, x + h) - explicit(order, x - h)) / (2.0 * h);
                    let h2 = 1e-3;
                    let d2 = (explicit(order, x + h2) - 2.0 * explicit(order, x)
                        + explicit(order, x - h2))
                        / (h2 * h2);
                    let diff = (got.value[k] - explicit(order, x)).abs();
                    assert!(diff < 1e-12, "{order} {w} {k} {diff:e}");
                    // Central differences: truncation O(h²) with derivatives of order one;
                    // the explicit sum cancels terms of ~10² (x up to 6), so its round-off
                    // is ~1e-14: 1e-14/h = 1e-10 in the first difference, 1e-14/h2² = 1e-8
                    // in the second (h2 = 1e-3, truncation h2²/12 ≈ 1e-7).
                    assert!((got.first[k] - d1).abs() < 1e-7, "{order} {w} {k}");
                    assert!((got.second[k] - d2).abs() < 1e-6, "{order} {w} {k}");
                }
            }
        }
    }
}
