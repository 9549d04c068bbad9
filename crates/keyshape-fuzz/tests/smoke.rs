//! A short, deterministic smoke of the fuzz targets (fuzz/fuzz_targets/*.rs) that runs on
//! the stable toolchain in every `cargo test`: each seed in fuzz/seeds/<target>/ and a few
//! thousand byte-level mutations of it (bit flips, byte insertions and deletions,
//! truncation, repeated and swapped slices) go through the same code
//! (`keyshape_fuzz`). No panic, and
//! whatever parses satisfies the readers' invariants. The long runs are `tools/fuzz.sh`
//! (cargo fuzz, nightly); see docs/src/testing.md.

// Test code: a failed unwrap is a failed test with its message.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use keyshape_fuzz as fuzzing;
use std::path::PathBuf;

const MUTATIONS_PER_SEED: usize = 300;

fn seeds(target: &str) -> Vec<Vec<u8>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/seeds")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no seeds in {}", dir.display());
    files.iter().map(|f| std::fs::read(f).unwrap()).collect()
}

/// xorshift64*: the same mutations on every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    let interesting: &[&[u8]] = &[
        b",",
        b"\n",
        b"-",
        b"1e308",
        b"NaN",
        b"inf",
        b"9223372036854775807",
        b"\"",
        b"{",
        b"}",
        b"<",
        b">",
        b"x_",
        b"frame",
        b"0",
        b"..",
        b"/",
        b" ",
    ];
    for _ in 0..1 + rng.below(4) {
        if v.is_empty() {
            v.push(b'0');
        }
        let at = rng.below(v.len());
        match rng.below(7) {
            0 => v[at] ^= 1 << rng.below(8),
            1 => {
                v.remove(at);
            }
            2 => v.insert(at, rng.next() as u8),
            3 => v.truncate(at),
            4 => {
                let tok = interesting[rng.below(interesting.len())];
                v.splice(at..at, tok.iter().copied());
            }
            5 => {
                let end = (at + 1 + rng.below(64)).min(v.len());
                let piece = v[at..end].to_vec();
                let to = rng.below(v.len());
                v.splice(to..to, piece);
            }
            _ => {
                let end = (at + 1 + rng.below(16)).min(v.len());
                let tok = interesting[rng.below(interesting.len())];
                v.splice(at..end, tok.iter().copied());
            }
        }
    }
    v
}

fn each_mutation(target: &str, check: fn(&[u8])) {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for seed in seeds(target) {
        check(&seed);
        for _ in 0..MUTATIONS_PER_SEED {
            check(&mutate(&seed, &mut rng));
        }
    }
}

#[test]
fn sequence_readers_survive_mutated_real_files() {
    each_mutation("sequence", fuzzing::sequence);
}

#[test]
fn the_gzip_layer_survives_mutated_archives() {
    each_mutation("gzip", fuzzing::gzip);
}

#[test]
fn the_svg_template_reader_survives_mutated_templates() {
    each_mutation("svg", fuzzing::svg);
}

#[test]
fn the_obj_reader_survives_mutated_meshes() {
    each_mutation("obj", fuzzing::obj);
}

#[test]
fn the_experiment_reader_survives_mutated_specs() {
    each_mutation("toml", fuzzing::toml);
}
