#!/usr/bin/env python3
"""How much the neutral frame matters for agreement with py-feat (README "Against
py-feat's own scores"). Solves the news sample from every STEP-th frame as `--neutral`
(default 3: 159 solves, about a minute), then prints, over those solves, the correlation of
the mean r (the summary of `tools/rig_vs_pyfeat.py`) with how active py-feat scores the
neutral frame (the sum of its scores, gaze left out) and with the solve's RMS landmark
error, and the best and worst neutral. Usage:

    cargo build --release && python3 tools/rig_neutral_sweep.py [STEP]

Analysis only: kslab does not need Python.
"""
import re
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import rig_vs_pyfeat as rv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
KSLAB = ROOT / "target/release/kslab"


def pearson(a, b):
    r = rv.pearson(a, b)
    return 0.0 if r is None else r


def main():
    step = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    news = rv.read(rv.NEWS)
    names = [c for c in news[0] if c[0].islower() and c not in ("clip", "frame")
             and not c.startswith(("x_", "y_"))]
    moved = [n for n in names if not n.startswith("eyeLook")
             and rv.std([float(r[n]) for r in news]) >= 0.02]
    activity = [sum(float(r[n]) for n in names if not n.startswith("eyeLook")) for r in news]
    peer = {n: [float(r[n]) for r in news] for n in moved}
    rows = []
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "w.csv"
        for f in range(0, len(news), step):
            p = subprocess.run([str(KSLAB), "rig", str(rv.NEWS), "-q", "--neutral", str(f),
                                "--out", str(out)], capture_output=True, text=True, check=True)
            rms = float(re.search(r"RMS landmark error ([0-9.]+)", p.stdout + p.stderr)[1])
            series = rv.read_series(out)
            rs = [pearson(series[n], peer[n]) if n in series else 0.0 for n in moved]
            rows.append((f, rms, sum(rs) / len(rs), activity[f]))
    mean_r = [r[2] for r in rows]
    print(f"{len(rows)} neutral frames (frames 0, {step}, {2 * step}, …), mean r over the {len(moved)} shapes")
    print(f"corr(mean r, py-feat activity of the neutral) = {pearson(mean_r, [r[3] for r in rows]):.2f}")
    print(f"corr(mean r, RMS landmark error)              = {pearson(mean_r, [r[1] for r in rows]):.2f}")
    best = max(rows, key=lambda r: r[2])
    worst = min(rows, key=lambda r: r[2])
    low = min(rows, key=lambda r: r[1])
    print(f"best neutral {best[0]}: mean r {best[2]:.3f} (RMS {best[1]:.2f} px)")
    print(f"worst neutral {worst[0]}: mean r {worst[2]:.3f} (RMS {worst[1]:.2f} px)")
    print(f"lowest RMS {low[0]}: mean r {low[2]:.3f} (RMS {low[1]:.2f} px)")
    print(f"mean over all neutrals: {sum(mean_r) / len(mean_r):.3f}")


if __name__ == "__main__":
    main()
