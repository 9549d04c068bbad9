//! Maximum spread along principal components (paper 000 §4.2).

use super::{Analysis, Heuristic, Selection};
use crate::error::Result;

/// For axes 1, 2, … take the frame with the largest, then the smallest, projection; k/2
/// axes for k key shapes. An odd k takes only the maximum on its last axis. A frame already
/// chosen is never chosen again: the next-most-extreme frame on that side is taken instead.
#[derive(Debug, Clone, Copy)]
pub struct Spread;

impl Heuristic for Spread {
    fn name(&self) -> String {
        "spread".into()
    }

    fn select(&self, an: &Analysis, k: usize) -> Result<Selection> {
        an.check_k(k)?;
        let axes = k.div_ceil(2);
        an.need_axes(axes, "spread")?;
        let n = an.frames();
        let mut taken = vec![false; n];
        let mut columns = Vec::with_capacity(k);
        for a in 0..axes {
            let row = an.proj.row(a);
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&i, &j| row[j].total_cmp(&row[i]).then(i.cmp(&j)));
            for side in 0..2 {
                if columns.len() == k {
                    break;
                }
                let pick = if side == 0 {
                    order.iter().copied().find(|&c| !taken[c])
                } else {
                    order.iter().rev().copied().find(|&c| !taken[c])
                };
                if let Some(c) = pick {
                    taken[c] = true;
                    columns.push(c);
                }
            }
        }
        Ok(Selection::frames(columns))
    }
}
