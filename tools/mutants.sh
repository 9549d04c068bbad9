#!/usr/bin/env bash
# Mutation testing of the numeric core (issue 12): one plausible bug at a time, the whole test
# suite after each. Needs `cargo install cargo-mutants`. Usage:
#   tools/mutants.sh                      # every file below (3,583 mutants: ~12 hours on 2 cores)
#   tools/mutants.sh -f src/decompose.rs  # just these files (replaces the list)
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
  src/solve/active_set.rs src/solve/mod.rs src/solve/lstsq.rs src/solve/chol.rs
  src/solve/jacobi.rs src/solve/textbook.rs src/solve/temporal/*.rs src/solve/filters.rs
  src/decompose.rs src/keyshapes/mod.rs src/keyshapes/spread.rs src/keyshapes/kmeans.rs
  src/keyshapes/hull.rs src/keyshapes/greedy.rs src/keyshapes/random.rs
  src/keyshapes/curves.rs
  src/cosker/modes.rs src/cosker/trajectory.rs src/cosker/morph.rs src/cosker/intensity.rs
  src/retarget/rbf.rs src/transfer/mod.rs src/transfer/skin.rs src/transfer/features.rs
)
args=()
if [[ " $* " != *" -f "* && " $* " != *" --file "* ]]; then
  for f in "${files[@]}"; do args+=(-f "$f"); done
fi
# --gitignore false: copy tools/gltf/node_modules too (the glTF tests need the validator).
# After --: every test target but the doc test, whose recompilation would double each run,
# and without the fuzz smoke (reader robustness: it kills no numeric mutant).
exec cargo mutants --profile mutants --gitignore false -o mutants "${args[@]}" "$@" \
  -- --all-targets -- --skip fuzz_smoke
