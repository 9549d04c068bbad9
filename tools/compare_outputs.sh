#!/usr/bin/env bash
# Runs every experiment of experiments/, and the commands listed below, with two kslab
# binaries and compares what they write: every CSV and PNG byte for byte (cmp), every
# report.json with its timings ("timings_s") left out (they are wall-clock seconds). For a change meant to keep every output (a move, a
# split, a refactor). Usage:
#   tools/compare_outputs.sh REV                # the build of git revision REV against this tree's
#   tools/compare_outputs.sh OLD_KSLAB NEW_KSLAB  # two binaries
# REV is built in a temporary git worktree with its own target folder (a few minutes).
# Exits 1 when any output differs, listing each. A CSV whose records parse the same but
# whose bytes differ (quoting) is listed apart, and passes with ALLOW_QUOTING=1.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"; git -C "$repo" worktree remove --force "$work/tree" 2>/dev/null || true' EXIT
if [ $# -eq 1 ]; then
  git worktree add -q --detach "$work/tree" "$1"
  (cd "$work/tree" && CARGO_TARGET_DIR="$work/target" cargo build --release --quiet --bin kslab)
  old="$work/target/release/kslab"
  cargo build --release --quiet --bin kslab
  new="$repo/target/release/kslab"
elif [ $# -eq 2 ]; then
  old=$1 new=$2
else
  sed -n 2,10p "$0" >&2
  exit 2
fi
for side in old new; do
  bin=${!side}
  for f in experiments/*.toml; do
    n=$(basename "$f" .toml)
    if ! "$bin" run "$f" --out "$work/$side/$n" -q >"$work/$side-$n.log" 2>&1; then
      echo "$side: $f failed: $(tail -1 "$work/$side-$n.log")" >&2
    fi
  done
done
# The commands whose CSVs no experiment writes: weights, head pose, Live Link, trajectories,
# the rig benchmark's tables and tracks. {OUT} is each side's folder.
D=../shared/data
cli=(
  "solve $D/mediapipe_face_tracks/liveportrait_d6.csv --points lips --keys 0,60,120,180 --solver nnls --out {OUT}/solve.csv"
  "solve $D/mediapipe_face_tracks/liveportrait_d6.csv --keys 0,60,120,180 --stream --out {OUT}/solve_stream.csv"
  "retarget --method spread --k 8 --solver nnls --out {OUT}/retarget.csv"
  "retarget --method spread --k 8 --solver ls --head-motion none --out {OUT}/retarget_aligned.csv"
  "rig $D/mediapipe_face_tracks/liveportrait_d6.csv --out {OUT}/rig.csv --pose {OUT}/rig_pose.csv --livelink {OUT}/rig_livelink.csv"
  "rig-accuracy --kind smooth --out {OUT}/accuracy.csv --tracks {OUT}/acc"
  "map $D/mediapipe_face_tracks/liveportrait_d6.csv --actions assets/actions/actions_liveportrait_d6.json --out {OUT}/map.csv"
  "smooth --method spread --k 8 --solver nnls --out {OUT}/smooth"
)
for side in old new; do
  bin=${!side}
  mkdir -p "$work/$side/cli"
  for c in "${cli[@]}"; do
    # shellcheck disable=SC2086
    if ! "$bin" ${c//\{OUT\}/$work/$side/cli} -q >"$work/$side-cli.log" 2>&1; then
      echo "$side: kslab $c failed: $(tail -1 "$work/$side-cli.log")" >&2
    fi
  done
done
python3 - "$work/old" "$work/new" <<'PY'
import filecmp, json, os, sys
old, new = sys.argv[1:]
def files(root):
    return {os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs}
a, b = files(old), files(new)
bad = [f"only in one run: {f}" for f in sorted(a ^ b)]
def strip(o):
    if isinstance(o, dict):
        return {k: strip(v) for k, v in o.items() if k not in ("timings", "timings_s")}
    if isinstance(o, list):
        return [strip(v) for v in o]
    return o
import csv
def records(path):
    with open(path, newline="") as fh:
        return list(csv.reader(fh))
same = 0
quoting = []
for f in sorted(a & b):
    p, q = os.path.join(old, f), os.path.join(new, f)
    if f.endswith(".json"):
        ok = strip(json.load(open(p))) == strip(json.load(open(q)))
    else:
        ok = filecmp.cmp(p, q, shallow=False)
    if ok:
        same += 1
    elif f.endswith(".csv") and records(p) == records(q):
        # The same fields, only quoted differently: listed, and a failure unless
        # ALLOW_QUOTING=1 (a change of CSV writer may quote only where it must).
        quoting.append(f)
    else:
        bad.append(f"differs: {f}")
for f in quoting:
    line = f"same records, quoted differently: {f}"
    if os.environ.get("ALLOW_QUOTING") == "1":
        print(line, file=sys.stderr)
    else:
        bad.append(line)
for line in bad:
    print(line, file=sys.stderr)
print(f"{same} of {len(a | b)} outputs identical (report.json: all but timings)"
      + (f", {len(quoting)} with the same records quoted differently" if quoting else ""))
sys.exit(1 if bad else 0)
PY
