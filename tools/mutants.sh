#!/usr/bin/env bash
# Mutation testing of the numeric core (issue 12): one plausible bug at a time, the whole test
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
files=(
  crates/keyshape-core/src/solve/active_set.rs crates/keyshape-core/src/solve/mod.rs crates/keyshape-core/src/solve/lstsq.rs crates/keyshape-core/src/solve/chol.rs
  crates/keyshape-core/src/solve/jacobi.rs crates/keyshape-core/src/solve/textbook.rs crates/keyshape-core/src/solve/temporal/*.rs crates/keyshape-core/src/solve/filters.rs
  crates/keyshape-core/src/decompose.rs crates/keyshape-core/src/keyshapes/mod.rs crates/keyshape-core/src/keyshapes/spread.rs crates/keyshape-core/src/keyshapes/kmeans.rs
  crates/keyshape-core/src/keyshapes/hull.rs crates/keyshape-core/src/keyshapes/greedy.rs crates/keyshape-core/src/keyshapes/random.rs
  crates/keyshape-core/src/keyshapes/curves.rs
  crates/keyshape-actions/src/modes.rs crates/keyshape-actions/src/trajectory.rs crates/keyshape-io/src/morph.rs crates/keyshape-actions/src/morph.rs crates/keyshape-actions/src/intensity.rs
  crates/keyshape-core/src/rbf.rs crates/keyshape-transfer/src/lib.rs crates/keyshape-transfer/src/skin.rs crates/keyshape-transfer/src/features.rs
)
args=()
if [[ " $* " != *" -f "* && " $* " != *" --file "* ]]; then
  for f in "${files[@]}"; do args+=(-f "$f"); done
fi
# --gitignore false: copy tools/gltf/node_modules too (the glTF tests need the validator).
# After --: every test target but the doc test, whose recompilation would double each run,
# and without the fuzz smoke (reader robustness: it kills no numeric mutant).
# --test-workspace true: a mutant in a library crate is tested by every crate's tests and
# the binary's end-to-end tests (tests/it), as before the workspace split, not only by its
# own crate's unit tests.
exec cargo mutants --profile mutants --gitignore false --test-workspace true -o mutants "${args[@]}" "$@" \
  -- --all-targets -- --skip fuzz_smoke
