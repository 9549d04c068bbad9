#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each (default 150), seeded from fuzz/seeds/<target>,
# growing fuzz/corpus/<target> (not committed). Needs the nightly toolchain and cargo-fuzz
# (`cargo install cargo-fuzz`). A crash stops the run and leaves fuzz/artifacts/<target>/.
# Usage: tools/fuzz.sh [SECONDS] [TARGET ...]
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
secs=${1:-150}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(sequence gzip svg obj toml)
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t"
  echo "== $t: ${secs}s"
  cargo +nightly fuzz run -O "$t" "corpus/$t" "seeds/$t" -- \
    -max_total_time="$secs" -max_len=65536 -rss_limit_mb=4096 -print_final_stats=1 2>&1 |
    grep -E "^(#[0-9]+.*DONE|Done|stat::number_of_executed_units|stat::peak_rss|==|.*panicked|.*ERROR)" || true
  if ls "artifacts/$t"/crash-* >/dev/null 2>&1; then
    echo "crash in $t: see fuzz/artifacts/$t" >&2
    exit 1
  fi
done
