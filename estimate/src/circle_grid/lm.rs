//! A small dense Levenberg-Marquardt over a residual function, with a forward-difference
//! Jacobian: the fits here have at most about a hundred parameters and a few thousand residuals.

use nalgebra::{DMatrix, DVector};

/// The most iterations of a fit (each solves the damped normal equations once or more).
const MAX_ITERATIONS: usize = 200;
/// Stop when a step lowers the cost by less than this fraction of it.
const RELATIVE_COST_TOLERANCE: f64 = 1e-12;

/// What a fit ended with: the parameters and the iterations taken.
#[derive(Debug, Clone)]
pub(super) struct LmResult {
    pub params: DVector<f64>,
    pub iterations: usize,
}

/// Minimises `sum residuals(p)^2` from `start`. `step_scale[i]` is the size of parameter `i`
/// (its finite-difference step is 1e-7 of it). None when the residuals are not finite at the
/// start.
pub(super) fn minimise(
    start: DVector<f64>,
    step_scale: &DVector<f64>,
    residuals: &dyn Fn(&DVector<f64>) -> DVector<f64>,
) -> Option<LmResult> {
    let mut p = start;
    let mut r = residuals(&p);
    let mut cost = r.norm_squared();
    if !cost.is_finite() {
        return None;
    }
    let mut damping = 1e-3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let jac = jacobian(&p, &r, step_scale, residuals);
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let mut improved = false;
        // Raise the damping until a step lowers the cost (bounded: a step that never helps
        // means a minimum).
        for _ in 0..12 {
            let mut a = jtj.clone();
            for i in 0..a.nrows() {
                a[(i, i)] += damping * jtj[(i, i)].max(1e-12);
            }
            let Some(chol) = a.cholesky() else {
                damping *= 10.0;
                continue;
            };
            let step = chol.solve(&(-&jtr));
            let trial = &p + &step;
            let r_trial = residuals(&trial);
            let c_trial = r_trial.norm_squared();
            if c_trial.is_finite() && c_trial < cost {
                let gain = (cost - c_trial) / cost.max(f64::MIN_POSITIVE);
                (p, r, cost) = (trial, r_trial, c_trial);
                damping = (damping * 0.3).max(1e-12);
                improved = gain > RELATIVE_COST_TOLERANCE;
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Some(LmResult {
        params: p,
        iterations,
    })
}

/// Forward differences, one parameter at a time.
fn jacobian(
    p: &DVector<f64>,
    r: &DVector<f64>,
    step_scale: &DVector<f64>,
    residuals: &dyn Fn(&DVector<f64>) -> DVector<f64>,
) -> DMatrix<f64> {
    let mut jac = DMatrix::zeros(r.len(), p.len());
    let mut q = p.clone();
    for i in 0..p.len() {
        let h = 1e-7 * step_scale[i].abs().max(1e-9);
        q[i] = p[i] + h;
        let column = (residuals(&q) - r) / h;
        jac.set_column(i, &column);
        q[i] = p[i];
    }
    jac
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_curve() {
        // y = a exp(b x) through exact points.
        let xs: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let residuals = |p: &DVector<f64>| {
            DVector::from_iterator(
                xs.len(),
                xs.iter()
                    .map(|&x| p[0] * (p[1] * x).exp() - 2.0 * (0.7 * x).exp()),
            )
        };
        let fit = minimise(
            DVector::from_vec(vec![1.0, 0.1]),
            &DVector::from_element(2, 1.0),
            &residuals,
        )
        .unwrap();
        assert!(
            (fit.params[0] - 2.0).abs() < 1e-6 && (fit.params[1] - 0.7).abs() < 1e-6,
            "{:?}",
            fit.params
        );
    }
}
