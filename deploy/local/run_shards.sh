#!/usr/bin/env bash
# Runs a corpus study's N shards as N parallel processes on this machine, then merges
# them into OUT/merged, exactly as the Slurm and Kubernetes set-ups do on a cluster.
#   bash deploy/local/run_shards.sh SPEC N OUT
# KSLAB names the binary (default: this repository's target/release/kslab, else kslab on PATH).
set -euo pipefail
if [ $# -ne 3 ]; then
  echo "usage: $0 SPEC N OUT" >&2
  exit 2
fi
repo=$(cd "$(dirname "$0")/../.." && pwd)
if [ -z "${KSLAB:-}" ]; then
  if [ -x "$repo/target/release/kslab" ]; then KSLAB="$repo/target/release/kslab"; else KSLAB=kslab; fi
fi
spec=$1 n=$2 out=$3
pids=()
for i in $(seq 0 $((n - 1))); do
  "$KSLAB" run "$spec" --quiet --shard "$i/$n" --out "$out/shard-$i" >/dev/null &
  pids+=($!)
done
failed=0
for i in "${!pids[@]}"; do
  if ! wait "${pids[$i]}"; then
    echo "error: shard $i/$n failed" >&2
    failed=1
  fi
done
[ "$failed" = 0 ] || exit 1
"$KSLAB" merge "$out"/shard-* --out "$out/merged"
