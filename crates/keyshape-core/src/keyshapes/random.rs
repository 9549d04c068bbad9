//! Uniformly random distinct frames, seeded: the floor every heuristic must beat.

use super::{Analysis, Heuristic, Selection};
use crate::error::Result;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// k distinct frames by a partial Fisher–Yates shuffle from a seeded xoshiro256++.
#[derive(Debug, Clone, Copy)]
pub struct Random {
    /// The seed; the same seed gives the same frames.
    pub seed: u64,
}

impl Heuristic for Random {
    fn name(&self) -> String {
        "random".into()
    }

    fn select(&self, an: &Analysis, k: usize) -> Result<Selection> {
        an.check_k(k)?;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(self.seed);
        let mut idx: Vec<usize> = (0..an.frames()).collect();
        for i in 0..k {
            let j = rng.gen_range(i..idx.len());
            idx.swap(i, j);
        }
        idx.truncate(k);
        Ok(Selection::frames(idx))
    }
}
