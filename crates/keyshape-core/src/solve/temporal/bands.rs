//! The difference operator's bands: `DᵀD` of order 1 or 2, as the banded system needs them.

/// The bands of `DᵀD` for `t` frames: `band[j][i]` is entry `(i, i − j)`, j = 0..=order.
pub fn difference_bands(order: usize, t: usize) -> Vec<Vec<f64>> {
    let coef: &[f64] = if order == 1 {
        &[-1.0, 1.0]
    } else {
        &[1.0, -2.0, 1.0]
    };
    let mut band = vec![vec![0.0; t]; order + 1];
    if t > order {
        // Row r of D touches frames r..=r+order.
        for r in 0..t - order {
            for a in 0..=order {
                for b in 0..=a {
                    band[a - b][r + a] += coef[a] * coef[b];
                }
            }
        }
    }
    band
}
