#!/usr/bin/env bash
# Runs a corpus study (an experiment with `inputs = [...]`) on Slurm as an array of N
# shards, waits for all of them, and merges their partial reports into OUT/merged: the
# report an unsharded `kslab run SPEC` writes. Fails if any shard fails (sbatch --wait
# returns non-zero) or if the merge finds a shard missing.
#   bash deploy/slurm/run_study.sh SPEC N OUT
# KSLAB names the binary (default: this repository's target/release/kslab, else kslab on PATH).
set -euo pipefail
if [ $# -ne 3 ]; then
  echo "usage: $0 SPEC N OUT" >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
spec=$(realpath "$1")
n=$2
mkdir -p "$3"
out=$(realpath "$3")
if [ -z "${KSLAB:-}" ]; then
  if [ -x "$repo/target/release/kslab" ]; then KSLAB="$repo/target/release/kslab"; else KSLAB=kslab; fi
fi
export KSLAB
sbatch --wait --array="0-$((n - 1))" --output="$out/slurm-%A_%a.out" --export=ALL \
  "$here/study.sbatch" "$spec" "$out"
"$KSLAB" merge "$out"/shard-* --out "$out/merged"
