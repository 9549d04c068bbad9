#!/usr/bin/env bash
# Seconds from starting the lab on a track with --rig to the screen showing the rig
# preview ("first frame alone") and the take ("track + posed rig"): the lab runs in a tmux
# server of its own, its screen polled every 20 ms. BENCHMARKS.md, "A preview of the
# current frame".
#
#     tools/lab_rig_timing.sh [KSLAB] [TRACK] [RIG]
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/kslab}
track=${2:-../shared/data/mediapipe_face_tracks/liveportrait_d6.csv}
rig=${3:-../shared/data/ict_facekit_face}
sock=kslab-timing-$$
trap 'tmux -L "$sock" kill-server 2>/dev/null || true' EXIT
start=$(date +%s.%N)
tmux -L "$sock" new-session -d -x 120 -y 34 "$bin tui $track --rig $rig"
preview=none
take=none
for _ in $(seq 1 1000); do
  screen=$(tmux -L "$sock" capture-pane -p 2>/dev/null || true)
  now=$(date +%s.%N)
  if [ "$preview" = none ] && grep -q "first frame alone" <<<"$screen"; then
    preview=$(echo "$now - $start" | bc)
  fi
  if grep -q "track + posed rig" <<<"$screen"; then
    take=$(echo "$now - $start" | bc)
    break
  fi
  sleep 0.02
done
echo "preview $preview s, take $take s"
