//! A small in-place Cholesky solve for the active-set sub-problems (p ≤ a few dozen), kept
//! allocation-free because it runs millions of times in a batch.

/// Solves `A x = rhs` for a symmetric positive definite `p × p` matrix stored row-major in
/// `a` (overwritten by its Cholesky factor); `rhs` becomes `x`. Returns false when a pivot
/// is not positive (A singular to working precision).
pub fn solve_spd(a: &mut [f64], p: usize, rhs: &mut [f64]) -> bool {
    let tiny = f64::EPSILON * (0..p).map(|i| a[i * p + i].abs()).fold(0.0, f64::max) * p as f64;
    for j in 0..p {
        let mut d = a[j * p + j];
        for k in 0..j {
            d -= a[j * p + k] * a[j * p + k];
        }
        if d <= tiny || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j * p + j] = d;
        for i in j + 1..p {
            let mut v = a[i * p + j];
            for k in 0..j {
                v -= a[i * p + k] * a[j * p + k];
            }
            a[i * p + j] = v / d;
        }
    }
    solve_factored(a, p, p, rhs);
    true
}

/// Solves `L Lᵀ x = rhs` in place for the Cholesky factor `L` (`p × p`, lower triangle,
/// row-major with row stride `ld ≥ p`): forward `L y = rhs`, then backward `Lᵀ x = y`.
pub(crate) fn solve_factored(l: &[f64], ld: usize, p: usize, rhs: &mut [f64]) {
    // Forward: L y = rhs.
    for i in 0..p {
        let mut v = rhs[i];
        for k in 0..i {
            v -= l[i * ld + k] * rhs[k];
        }
        rhs[i] = v / l[i * ld + i];
    }
    // Backward: Lᵀ x = y.
    for i in (0..p).rev() {
        let mut v = rhs[i];
        for k in i + 1..p {
            v -= l[k * ld + i] * rhs[k];
        }
        rhs[i] = v / l[i * ld + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_known_system_and_rejects_a_singular_one() {
        let mut a = vec![4.0, 2.0, 2.0, 3.0];
        let mut b = vec![2.0, 1.0];
        assert!(solve_spd(&mut a, 2, &mut b));
        assert!((b[0] - 0.5).abs() < 1e-15 && b[1].abs() < 1e-15);
        let mut s = vec![1.0, 1.0, 1.0, 1.0];
        assert!(!solve_spd(&mut s, 2, &mut [1.0, 1.0]));
    }

    /// A generic 4 × 4 system (B Bᵀ + I) is solved: A x reproduces the right side.
    #[test]
    fn solves_a_generic_system_to_rounding() {
        let b: Vec<f64> = (0..16)
            .map(|i| ((i * 7 + 3) % 11) as f64 / 3.0 - 1.5)
            .collect();
        let mut a = vec![0.0; 16];
        for i in 0..4 {
            for j in 0..4 {
                a[i * 4 + j] = (0..4).map(|k| b[i * 4 + k] * b[j * 4 + k]).sum::<f64>()
                    + if i == j { 1.0 } else { 0.0 };
            }
        }
        let orig = a.clone();
        let rhs = [1.0, -2.0, 0.5, 3.0];
        let mut x = rhs;
        assert!(solve_spd(&mut a, 4, &mut x));
        for i in 0..4 {
            let ax: f64 = (0..4).map(|j| orig[i * 4 + j] * x[j]).sum();
            assert!(
                (ax - rhs[i]).abs() < 1e-12,
                "row {i}: {ax} against {}",
                rhs[i]
            );
        }
    }

    /// The singularity threshold is exactly `ε · max|aᵢᵢ| · p`: a pivot at or below it is
    /// refused, one just above accepted — each case sits between the formula and a slip in
    /// it (÷ p, ÷ max, the wrong diagonal), so the formula is pinned, not just its order.
    #[test]
    fn the_pivot_threshold_is_epsilon_times_the_largest_diagonal_times_p() {
        let e = f64::EPSILON;
        // Pivot ε against a threshold ≈ 2ε (÷ p would make it ε/2).
        assert!(!solve_spd(
            &mut [1.0, 1.0, 1.0, 1.0 + e],
            2,
            &mut [1.0, 1.0]
        ));
        // Pivot 4ε against ≈ 8ε (÷ max would make it ε/2).
        assert!(!solve_spd(
            &mut [4.0, 4.0, 4.0, 4.0 + 4.0 * e],
            2,
            &mut [1.0, 1.0]
        ));
        // The largest diagonal is the second: pivot 2ε against 2ε(1 + 2ε); reading an
        // off-diagonal entry as the diagonal would make the threshold ε.
        assert!(!solve_spd(
            &mut [0.25, 0.5, 0.5, 1.0 + 2.0 * e],
            2,
            &mut [1.0, 1.0]
        ));
        // Just above: pivot 8ε against 2ε(1 + 8ε) is accepted and solves exactly.
        let mut a = [1.0, 1.0, 1.0, 1.0 + 8.0 * e];
        let mut b = [1.0, 1.0 + 8.0 * e];
        assert!(solve_spd(&mut a, 2, &mut b));
        assert!(
            (b[0] - 0.0).abs() < 1e-12 && (b[1] - 1.0).abs() < 1e-12,
            "{b:?}"
        );
    }
}
