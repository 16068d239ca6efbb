//! The autoregressive forecaster's numerics: the least-squares fit's normal equations and their
//! truncated solve, the bound on the fitted recursion's roots (the Schur-Cohn step-down test),
//! the covariance step of the gap filter, and the resampling onto the fit's grid.

use nalgebra::{DMatrix, DVector};

/// Singular values of the autoregressive fit's design below this share of the largest are
/// left out. A motion with fewer frequencies than the order leaves directions of the
/// coefficients the data do not fix; solved as they come, they take values that fit the window
/// exactly and then, fed the model's own forecasts, oscillate (a noise-free sea cleared into a
/// heave rate 10 % over the limit). A ridge fixes that too but damps every forecast.
pub(super) const AR_CUTOFF: f64 = 1e-5;

/// Grid steps a forecast across a gap filters over beyond twice the order: the measured lags
/// before the gap, the gap, and the lags after it.
pub(super) const GAP_FILTER_EXTRA_STEPS: usize = 8;

/// A measurement's variance in the gap filter, as a share of one innovation's.
pub(super) const MEASUREMENT_SHARE: f64 = 1e-6;

/// `out = A P A'` for the recursion's companion matrix `A` (first row `a`, ones below the
/// diagonal): the state shifts by one, its newest value the recursion's. `O(p^2)` where a
/// product of dense matrices is `O(p^3)`.
pub(super) fn propagate(p: &DMatrix<f64>, a: &DVector<f64>, out: &mut DMatrix<f64>) {
    let n = a.len();
    // P a: the covariance of the new value with each old component (P is symmetric).
    let pa = p * a;
    out[(0, 0)] = a.dot(&pa);
    for j in 1..n {
        out[(0, j)] = pa[j - 1];
        out[(j, 0)] = pa[j - 1];
    }
    out.view_mut((1, 1), (n - 1, n - 1))
        .copy_from(&p.view((0, 0), (n - 1, n - 1)));
}

/// The normal equations `(A^T A, A^T b)` of the autoregression of order `p` on `x`: row `r` of
/// `A` is `x[r + p - 1], ..., x[r], 1` and `b[r] = x[r + p]`. Built from lagged products
/// `S(u, v) = sum_r x[r + u] x[r + v]`, whose neighbours along a diagonal differ by one term at
/// each end: `O(n p)` instead of the `O(n p^2)` of multiplying the design out.
pub fn normal_equations(x: &[f64], p: usize) -> (DMatrix<f64>, DVector<f64>) {
    let rows = x.len() - p;
    // Lags 0..=p: lag p is the target's.
    let lags = p + 1;
    let mut s = DMatrix::<f64>::zeros(lags, lags);
    for v in 0..lags {
        s[(0, v)] = dot(&x[..rows], &x[v..v + rows]);
    }
    for u in 1..lags {
        for v in u..lags {
            s[(u, v)] = s[(u - 1, v - 1)] - x[u - 1] * x[v - 1] + x[u - 1 + rows] * x[v - 1 + rows];
        }
    }
    let lagged = |u: usize, v: usize| s[(u.min(v), u.max(v))];
    let mut sums = vec![(0..rows).map(|r| x[r]).sum::<f64>(); lags];
    for u in 1..lags {
        sums[u] = sums[u - 1] - x[u - 1] + x[u - 1 + rows];
    }
    // Column i of A is lag p - 1 - i; the last column is the intercept's.
    let ata = DMatrix::from_fn(p + 1, p + 1, |i, j| match (i == p, j == p) {
        (true, true) => rows as f64,
        (true, false) => sums[p - 1 - j],
        (false, true) => sums[p - 1 - i],
        (false, false) => lagged(p - 1 - i, p - 1 - j),
    });
    let atb = DVector::from_fn(p + 1, |i, _| if i == p { sums[p] } else { lagged(p - 1 - i, p) });
    (ata, atb)
}

/// The lagged products `S(u, v) = sum_r a[r + u] b[r + v]` (`u, v` in `0..=p`) and the lagged
/// sums `sum_r a[r + u]` over the rows `r` of an autoregression of order `p` on grids `a`, `b`
/// of one length, the rows `gap_rows` (increasing) left out: what the joint fit's normal
/// equations are made of. Each run of kept rows is summed as [`normal_equations`] does, along
/// the diagonals (`O(rows p + runs p^2)`); multiplying the designs out is `O(rows p q)`, and
/// was the largest part of the joint refit's time on a 600 s window (a profile of the criterion
/// bench: the products and their packing about a quarter, building the designs a sixth).
pub(super) fn lagged_products(
    a: &[f64],
    b: &[f64],
    p: usize,
    gap_rows: &[usize],
) -> (DMatrix<f64>, Vec<f64>) {
    let mut products = DMatrix::<f64>::zeros(p + 1, p + 1);
    let mut sums = vec![0.0; p + 1];
    debug_assert_eq!(a.len(), b.len(), "the grids of one fit");
    let rows = a.len().min(b.len()).saturating_sub(p);
    debug_assert!(
        gap_rows.windows(2).all(|w| w[0] < w[1]) && gap_rows.last().is_none_or(|&r| r < rows),
        "gap rows increasing and inside the rows"
    );
    let mut start = 0;
    for end in gap_rows.iter().copied().chain(std::iter::once(rows)) {
        if end > start {
            add_run_products(
                &a[start..end + p],
                &b[start..end + p],
                p,
                &mut products,
                &mut sums,
            );
        }
        start = end + 1;
    }
    (products, sums)
}

/// [`lagged_products`] over every row of the grids `a`, `b` (length `rows + p`), added.
fn add_run_products(a: &[f64], b: &[f64], p: usize, products: &mut DMatrix<f64>, sums: &mut [f64]) {
    let rows = a.len() - p;
    let lagged = |u: usize, v: usize| dot(&a[u..u + rows], &b[v..v + rows]);
    // The first row and column start the diagonals; a step along one adds the row after the
    // run and takes the first away.
    let mut run = DMatrix::<f64>::zeros(p + 1, p + 1);
    for v in 0..=p {
        run[(0, v)] = lagged(0, v);
    }
    for u in 1..=p {
        run[(u, 0)] = lagged(u, 0);
    }
    for u in 1..=p {
        for v in 1..=p {
            run[(u, v)] = run[(u - 1, v - 1)] - a[u - 1] * b[v - 1] + a[u - 1 + rows] * b[v - 1 + rows];
        }
    }
    *products += run;
    let mut sum: f64 = a[..rows].iter().sum();
    sums[0] += sum;
    for u in 1..=p {
        sum += a[u - 1 + rows] - a[u - 1];
        sums[u] += sum;
    }
}

/// The dot product of `a` and `b` (of one length) in eight running sums: a single one is a chain
/// of dependent additions the compiler may not reorder, and the lagged products are most of a
/// refit's sums.
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let mut acc = [0.0; 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = a8
        .remainder()
        .iter()
        .zip(b8.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a8.zip(b8) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// The rows of the autoregression of order `p` (row `r`: target `r + p`, lags `r..r + p`) with
/// a grid point not measured, in increasing order.
pub(super) fn gap_rows(unmeasured: &[bool], p: usize) -> Vec<usize> {
    let rows = unmeasured.len().saturating_sub(p);
    let mut out = Vec::new();
    // The newest unmeasured point at or before each row's target, found in one pass.
    let mut last_unmeasured: Option<usize> = None;
    for (k, &u) in unmeasured.iter().enumerate().take(p) {
        if u {
            last_unmeasured = Some(k);
        }
    }
    for r in 0..rows {
        if unmeasured[r + p] {
            last_unmeasured = Some(r + p);
        }
        if last_unmeasured.is_some_and(|k| k >= r) {
            out.push(r);
        }
    }
    out
}

/// Row `r` of the design of [`normal_equations`] into `row` (length `p + 1`):
/// `x[r + p - 1], ..., x[r], 1`.
pub(super) fn design_row(x: &[f64], p: usize, r: usize, row: &mut DVector<f64>) {
    for (i, v) in row.iter_mut().enumerate() {
        *v = if i == p { 1.0 } else { x[r + p - 1 - i] };
    }
}

/// The largest root an autoregressive fit may keep: motion that neither grows nor stays.
pub(super) const MAX_ROOT_RADIUS: f64 = 0.999;

/// The solution of the normal equations `ata x = atb` (symmetric, positive semi-definite)
/// with the directions whose eigenvalue is below `AR_CUTOFF^2` of the largest left out; None
/// if they are not finite or the decomposition does not converge.
pub(super) fn truncated_solve(ata: DMatrix<f64>, atb: &DVector<f64>) -> Option<DVector<f64>> {
    if !atb.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(TruncatedInverse::new(ata)?.apply(atb))
}

/// The pseudo-inverse of normal equations (symmetric, positive semi-definite) with the
/// directions whose eigenvalue is below `AR_CUTOFF^2` of the largest left out, kept as its
/// eigen-decomposition: applied to several right-hand sides (the joint fit's Schur complement)
/// without decomposing again.
#[derive(Debug, Clone)]
pub(super) struct TruncatedInverse {
    vectors: DMatrix<f64>,
    /// The eigenvalues, None where left out.
    values: Vec<Option<f64>>,
}

impl TruncatedInverse {
    /// None if `ata` is not finite, has no positive eigenvalue, or does not converge.
    pub(super) fn new(ata: DMatrix<f64>) -> Option<Self> {
        if !ata.iter().all(|v| v.is_finite()) {
            return None;
        }
        let eigen = nalgebra::linalg::SymmetricEigen::try_new(ata, f64::EPSILON, 1000)?;
        let largest = eigen.eigenvalues.max();
        if !(largest > 0.0) {
            return None;
        }
        let values = eigen
            .eigenvalues
            .iter()
            .map(|&l| (l > AR_CUTOFF * AR_CUTOFF * largest).then_some(l))
            .collect();
        Some(Self {
            vectors: eigen.eigenvectors,
            values,
        })
    }

    /// The pseudo-inverse times `b` (a vector or the columns of a matrix).
    pub(super) fn apply<S: nalgebra::Dim, St: nalgebra::storage::Storage<f64, nalgebra::Dyn, S>>(
        &self,
        b: &nalgebra::Matrix<f64, nalgebra::Dyn, S, St>,
    ) -> nalgebra::OMatrix<f64, nalgebra::Dyn, S>
    where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<nalgebra::Dyn, S>,
    {
        let mut projected = self.vectors.tr_mul(b);
        for (mut row, value) in projected.row_iter_mut().zip(&self.values) {
            match value {
                Some(l) => row /= *l,
                None => row.fill(0.0),
            }
        }
        &self.vectors * projected
    }
}

/// `a` scaled so that every root of `z^p - a_1 z^(p-1) - ... - a_p` is within
/// `MAX_ROOT_RADIUS` (unchanged if they are); None when [`root_radius_bound`] finds none.
pub(super) fn with_roots_within_max_radius(a: &[f64]) -> Option<Vec<f64>> {
    let radius = root_radius_bound(a)?;
    let r = (MAX_ROOT_RADIUS / radius).min(1.0);
    Some(
        a.iter()
            .enumerate()
            .map(|(i, ai)| ai * r.powi(i as i32 + 1))
            .collect(),
    )
}

/// Relative width to which [`root_radius_bound`] brackets the roots' largest modulus.
const ROOT_RADIUS_TOLERANCE: f64 = 1e-9;

/// A radius that every root of `z^p - a_1 z^(p-1) - ... - a_p` lies within, at most
/// `ROOT_RADIUS_TOLERANCE` (relative) above the largest root's modulus, or `MAX_ROOT_RADIUS`
/// if they all lie within that; None if the coefficients are not finite, or if the step-down
/// cannot place the roots even at 256 times Cauchy's bound (rounding). Bisection with the
/// step-down test ([`roots_within`]), `O(p^2)` a step: the companion matrix's eigenvalues took
/// 2.3 ms at 96 lags, three quarters of a fit, and nalgebra's did not converge on some
/// matrices (a root at every 96th of the circle: docs/history.md, "The roots' radius by bisection"). A test too close to call counts as roots outside: the bound errs high, and a
/// fit is then damped a hair more, never less.
pub(super) fn root_radius_bound(a: &[f64]) -> Option<f64> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let within = |r: f64| roots_within(a, r) == Some(true);
    if within(MAX_ROOT_RADIUS) {
        return Some(MAX_ROOT_RADIUS);
    }
    // Cauchy's bound: every root lies within 1 + max |a_i|. Doubled while the test cannot
    // tell there (rounding), a few times at most.
    let mut hi = 1.0 + a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut doublings = 0;
    while !within(hi) {
        hi *= 2.0;
        doublings += 1;
        if doublings > 8 {
            return None;
        }
    }
    let mut lo = MAX_ROOT_RADIUS;
    while hi - lo > ROOT_RADIUS_TOLERANCE * hi {
        let mid = 0.5 * (lo + hi);
        if within(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// Reflection coefficients closer to 1 than this leave the step-down of [`roots_within`] to
/// rounding: it answers None, which [`root_radius_bound`] counts as roots outside.
const STEP_DOWN_MIN_GAP: f64 = 1e-9;

/// Whether every root of `z^p - a_1 z^(p-1) - ... - a_p` lies strictly within `radius`: the
/// Schur-Cohn test, `O(p^2)` where the companion matrix's eigenvalues are `O(p^3)`. With
/// `z = radius w` the roots in `w` must lie within the unit circle, which holds exactly when
/// every reflection coefficient of the step-down (Levinson's recursion run backwards) is below
/// 1 in size. None when that is too close to call or a value is not finite.
pub(super) fn roots_within(a: &[f64], radius: f64) -> Option<bool> {
    if !(radius > 0.0) {
        return None;
    }
    let mut phi: Vec<f64> = a
        .iter()
        .enumerate()
        .map(|(i, ai)| ai / radius.powi(i as i32 + 1))
        .collect();
    let mut next = vec![0.0; phi.len()];
    for m in (1..=phi.len()).rev() {
        let k = phi[m - 1];
        if !k.is_finite() {
            return None;
        }
        let gap = 1.0 - k * k;
        if gap.abs() < STEP_DOWN_MIN_GAP {
            return None;
        }
        if gap < 0.0 {
            return Some(false);
        }
        for j in 0..m - 1 {
            next[j] = (phi[j] + k * phi[m - 2 - j]) / gap;
        }
        phi[..m - 1].copy_from_slice(&next[..m - 1]);
    }
    Some(true)
}

/// The largest modulus of the roots of `z^p - a_1 z^(p-1) - ... - a_p` (the eigenvalues of the
/// recursion's companion matrix); NaN if they cannot be found. The tests' judge of
/// [`root_radius_bound`].
#[cfg(test)]
pub(super) fn companion_radius(a: &[f64]) -> f64 {
    let p = a.len();
    if !a.iter().all(|v| v.is_finite()) {
        return f64::NAN;
    }
    let companion = DMatrix::from_fn(p, p, |r, c| {
        if r == 0 {
            a[c]
        } else if r == c + 1 {
            1.0
        } else {
            0.0
        }
    });
    // A bounded number of iterations: the unbounded decomposition can loop for ever on some
    // matrices. NaN when it does not converge (the fit is then refused).
    match nalgebra::linalg::Schur::try_new(companion, f64::EPSILON, 1000) {
        Some(schur) => schur
            .complex_eigenvalues()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max),
        None => f64::NAN,
    }
}

/// `n` values on a uniform grid of step `dt` ending at the newest sample, linearly interpolated
/// between samples (before the first sample, the first value), and which of them were not
/// measured: inside a gap (samples more than `max_bridge_s` apart) or before the first sample.
pub(super) fn resample(t: &[f64], y: &[f64], dt: f64, n: usize, max_bridge_s: f64) -> (Vec<f64>, Vec<bool>) {
    let n_in = t.len();
    let t0 = t[n_in - 1];
    let mut x = vec![0.0; n];
    let mut unmeasured = vec![false; n];
    let mut j = n_in - 1;
    for (k, (xk, uk)) in x.iter_mut().zip(unmeasured.iter_mut()).enumerate().rev() {
        let g = t0 - (n - 1 - k) as f64 * dt;
        while j > 0 && t[j - 1] >= g {
            j -= 1;
        }
        (*xk, *uk) = if j == 0 {
            // (A grid point a rounding error before the first sample is that sample.)
            (y[0], g < t[0] - 1e-6 * dt)
        } else {
            let (ta, tb) = (t[j - 1], t[j]);
            let f = if tb > ta { (g - ta) / (tb - ta) } else { 1.0 };
            // A grid point on the sample that ends a gap (within a rounding) is that sample:
            // measured.
            (
                y[j - 1] + f.clamp(0.0, 1.0) * (y[j] - y[j - 1]),
                tb - ta > max_bridge_s && f < 1.0 - 1e-6,
            )
        };
    }
    (x, unmeasured)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forecast::ArModel;
    use std::f64::consts::TAU;

    #[test]
    fn the_normal_equations_from_lagged_products_are_the_designs() {
        // An irregular series with an offset: every lag and the intercept matter.
        let x: Vec<f64> = (0..90)
            .map(|k| 2.0 + (0.37 * k as f64).sin() + 0.1 * ((k * k) % 7) as f64)
            .collect();
        for p in [2usize, 5, 29] {
            let rows = x.len() - p;
            let a = DMatrix::from_fn(rows, p + 1, |r, i| if i == p { 1.0 } else { x[r + p - 1 - i] });
            let b = DVector::from_fn(rows, |r, _| x[r + p]);
            let (ata, atb) = normal_equations(&x, p);
            let scale = a.tr_mul(&a).amax();
            assert!((ata - a.tr_mul(&a)).amax() < 1e-12 * scale, "order {p}");
            assert!((atb - a.tr_mul(&b)).amax() < 1e-12 * scale, "order {p}");
        }
    }

    #[test]
    fn lagged_products_over_runs_of_rows_are_the_sums_over_those_rows() {
        let a: Vec<f64> = (0..120)
            .map(|k| 1.5 + (0.31 * k as f64).sin() + 0.05 * ((k * k) % 11) as f64)
            .collect();
        let b: Vec<f64> = (0..120)
            .map(|k| -0.5 + (0.23 * k as f64).cos() + 0.07 * ((k * 3) % 5) as f64)
            .collect();
        // No gap; gaps at the start, in the middle (two adjacent), at the end.
        let gap_sets: [&[usize]; 4] = [&[], &[0, 1, 2], &[40, 41, 60], &[100, 101, 102, 103]];
        for p in [2usize, 7, 16] {
            let rows = a.len() - p;
            for gaps in gap_sets {
                let kept: Vec<usize> = (0..rows).filter(|r| !gaps.contains(r)).collect();
                let (products, sums) = lagged_products(&a, &b, p, gaps);
                for u in 0..=p {
                    let sum: f64 = kept.iter().map(|&r| a[r + u]).sum();
                    assert!((sums[u] - sum).abs() < 1e-10, "order {p}, gaps {gaps:?}, sum {u}");
                    for v in 0..=p {
                        let product: f64 = kept.iter().map(|&r| a[r + u] * b[r + v]).sum();
                        assert!(
                            (products[(u, v)] - product).abs() < 1e-10 * product.abs().max(1.0),
                            "order {p}, gaps {gaps:?}, ({u}, {v})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_companion_radius_is_the_largest_roots_modulus() {
        // (z - 0.5)(z + 0.8) = z^2 + 0.3 z - 0.4: a_1 = -0.3, a_2 = 0.4.
        assert!((companion_radius(&[-0.3, 0.4]) - 0.8).abs() < 1e-12);
        // A damped oscillation, roots 0.95 e^(+-i 0.3), and a root at 0.2 beside it:
        // (z^2 - 2 r cos(w) z + r^2)(z - 0.2).
        let (r, w) = (0.95f64, 0.3f64);
        let (b1, b2) = (2.0 * r * w.cos(), -r * r);
        let a = [b1 + 0.2, b2 - 0.2 * b1, -0.2 * b2];
        assert!((companion_radius(&a) - 0.95).abs() < 1e-12);
        // Of order 96: x_k = 0.999 x_{k-96} has 96 roots of modulus 0.999^(1/96), evenly
        // around the circle. Nalgebra's Schur decomposition does not converge on it (NaN: no
        // fit); the step-down test places them.
        let mut a = vec![0.0; 96];
        a[95] = 0.999;
        let modulus = 0.999f64.powf(1.0 / 96.0);
        assert_eq!(roots_within(&a, modulus + 1e-7), Some(true));
        assert_eq!(roots_within(&a, modulus - 1e-7), Some(false));
        assert!(companion_radius(&[f64::NAN, 0.1]).is_nan());
    }

    #[test]
    fn the_step_down_test_agrees_with_the_roots() {
        assert_eq!(roots_within(&[-0.3, 0.4], 0.81), Some(true));
        assert_eq!(roots_within(&[-0.3, 0.4], 0.79), Some(false));
        assert_eq!(roots_within(&[f64::NAN, 0.4], 0.9), None);
        // Random recursions of every order up to 96, their roots on both sides of the radius;
        // and the fits of a sea-like series, whose roots crowd the unit circle.
        let mut state = 0x5EEDu64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = [0usize; 2];
        for trial in 0..400 {
            let order = 1 + trial % 96;
            let size = 0.2 + 1.6 * uniform();
            let a: Vec<f64> = (0..order)
                .map(|i| (2.0 * uniform() - 1.0) * size / (i + 1) as f64)
                .collect();
            let radius = companion_radius(&a);
            for r in [0.9, MAX_ROOT_RADIUS, 1.1] {
                if (radius - r).abs() < 1e-6 {
                    continue;
                }
                if let Some(inside) = roots_within(&a, r) {
                    assert_eq!(inside, radius < r, "order {order}, radius {radius}, r {r}");
                    checked[inside as usize] += 1;
                }
            }
        }
        assert!(checked.iter().all(|&n| n > 100), "{checked:?}");
        let dt = 0.2;
        let t: Vec<f64> = (0..600).map(|k| k as f64 * dt).collect();
        for noise in [0.0, 0.01, 0.1] {
            let y: Vec<f64> = t
                .iter()
                .map(|&t| {
                    3.0 * (TAU * t / 9.0).sin()
                        + 1.2 * (TAU * t / 6.5 + 1.0).sin()
                        + noise * (uniform() - 0.5)
                })
                .collect();
            let fit = ArModel::fit(&t, &y, 96, dt, 2.0, 0.5).unwrap();
            let a = &fit.coef[..96];
            assert!(companion_radius(a) <= MAX_ROOT_RADIUS + 1e-9, "noise {noise}");
            // Before it was pulled inside: the swells' roots on the circle, a hair outside.
            let (ata, atb) = normal_equations(&y, 96);
            let raw = truncated_solve(ata, &atb).unwrap();
            let raw = &raw.as_slice()[..96];
            let (bound, radius) = (root_radius_bound(raw).unwrap(), companion_radius(raw));
            assert!(radius > MAX_ROOT_RADIUS, "noise {noise}: {radius}");
            assert!(
                bound >= radius - 1e-12 && bound <= radius * (1.0 + 1e-6),
                "noise {noise}: {bound} against {radius}"
            );
        }
        // The bound against the roots on the random recursions.
        for trial in 0..200 {
            let order = 1 + trial % 96;
            let a: Vec<f64> = (0..order)
                .map(|i| (2.0 * uniform() - 1.0) * 1.5 / (i + 1) as f64)
                .collect();
            let radius = companion_radius(&a);
            if radius.is_finite() {
                let bound = root_radius_bound(&a).unwrap();
                assert!(
                    bound >= radius.max(MAX_ROOT_RADIUS) - 1e-12,
                    "order {order}: {bound} against {radius}"
                );
                assert!(
                    bound <= radius.max(MAX_ROOT_RADIUS) * (1.0 + 1e-6),
                    "order {order}: {bound} against {radius}"
                );
            }
        }
        assert_eq!(root_radius_bound(&[f64::INFINITY]), None);
        // A recursion that grows is pulled inside, its frequencies kept.
        let (r, w) = (1.02f64, 0.3f64);
        let pulled = with_roots_within_max_radius(&[2.0 * r * w.cos(), -r * r]).unwrap();
        let radius = companion_radius(&pulled);
        assert!(
            radius <= MAX_ROOT_RADIUS + 1e-12 && radius > MAX_ROOT_RADIUS - 1e-8,
            "{radius}"
        );
        assert!((pulled[0] / (2.0 * pulled[1].abs().sqrt()) - w.cos()).abs() < 1e-12);
        let calm = [-0.3, 0.4];
        assert_eq!(with_roots_within_max_radius(&calm).unwrap(), calm);
    }

    #[test]
    fn the_truncated_solve_leaves_out_what_the_data_do_not_fix() {
        // Full rank: the exact solution.
        let ata = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let x = DVector::from_column_slice(&[1.0, -2.0, 0.5]);
        let solved = truncated_solve(ata.clone(), &(&ata * &x)).unwrap();
        assert!((solved - &x).amax() < 1e-12);
        // Two equal columns: the direction (1, -1, 0) is not fixed, and the solution has none
        // of it (the least-norm one), where an inverse would blow up.
        let ata = DMatrix::from_row_slice(3, 3, &[2.0, 2.0, 1.0, 2.0, 2.0, 1.0, 1.0, 1.0, 3.0]);
        let atb = DVector::from_column_slice(&[4.0, 4.0, 5.0]);
        let solved = truncated_solve(ata.clone(), &atb).unwrap();
        assert!((solved[0] - solved[1]).abs() < 1e-9);
        assert!((&ata * &solved - &atb).amax() < 1e-9);
        assert!(truncated_solve(DMatrix::zeros(2, 2), &DVector::zeros(2)).is_none());
        let mut bad = ata.clone();
        bad[(1, 2)] = f64::INFINITY;
        assert!(truncated_solve(bad, &atb).is_none());
    }
}
