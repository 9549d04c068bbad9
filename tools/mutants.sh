#!/usr/bin/env bash
# Mutation testing of the numeric core: one plausible bug at a time, the whole test
# suite after each. Needs `cargo install cargo-mutants`. Usage:
#   tools/mutants.sh                      # every file below (3,583 mutants: ~12 hours on 2 cores)
#   tools/mutants.sh -f crates/keyshape-core/src/decompose.rs  # just these files (replaces the list)
#   tools/mutants.sh --shard 1/8          # one eighth of the full list, to spread over runs
# Results go to mutants/mutants.out/ (caught.txt, missed.txt, timeout.txt, unviable.txt);
# mutants/README.md says which survivors are equivalent and which tests killed the rest.
set -euo pipefail
cd "$(dirname "$0")/.."
# cargo-mutants builds a copy of the tree in $TMPDIR; the tests read ../shared/data from it.
tmp=${TMPDIR:-/tmp}
if [ ! -e "$tmp/shared" ]; then
  ln -s "$(cd ../shared && pwd)" "$tmp/shared"
fi
core=crates/keyshape-core/src
files=(
  $core/solve/active_set.rs $core/solve/mod.rs $core/solve/lstsq.rs $core/solve/chol.rs
  $core/solve/jacobi.rs $core/solve/textbook.rs $core/solve/temporal/*.rs $core/solve/filters.rs
  $core/decompose.rs $core/rbf.rs
  $core/keyshapes/mod.rs $core/keyshapes/spread.rs $core/keyshapes/kmeans.rs $core/keyshapes/hull.rs
  $core/keyshapes/greedy.rs $core/keyshapes/random.rs $core/keyshapes/curves.rs
  crates/keyshape-actions/src/{modes,trajectory,morph,intensity}.rs crates/keyshape-io/src/morph.rs
  crates/keyshape-transfer/src/{lib,skin,features}.rs
)
args=()
if [[ " $* " != *" -f "* && " $* " != *" --file "* ]]; then
  for f in "${files[@]}"; do args+=(-f "$f"); done
fi
# --gitignore false: copy tools/gltf/node_modules too (the glTF tests need the validator).
# After --: every test target but the doc test, whose recompilation would double each run,
# and without the fuzz smoke (reader robustness: it kills no numeric mutant).
# --workspace: mutate the library crates too (without it cargo-mutants mutates only the
# root package, the binary). --test-workspace true: a mutant in a library crate is tested
# by every crate's tests and the binary's end-to-end tests (tests/it), as before the
# workspace split, not only by its own crate's tests.
exec cargo mutants --workspace --profile mutants --gitignore false --test-workspace true -o mutants "${args[@]}" "$@" \
  -- --all-targets -- --skip fuzz_smoke
