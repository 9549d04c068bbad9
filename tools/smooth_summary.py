#!/usr/bin/env python3
"""Tables the smoothing study across tracks for the README.

Usage: for t in d6 d9 d18 pexels; do kslab run experiments/smooth_lips_$t.toml --out out/smooth_$t; done
       python3 tools/smooth_summary.py out/smooth_d6 out/smooth_d9 out/smooth_d18 out/smooth_pexels

For each run folder: the unsmoothed jitter and errors, then at 50 % and 35 % of the
unsmoothed jitter each approach's target error against the tracked reference G(q) and the
clean reference G(q~) (from smoothing_at_equal_jitter.csv), the best of each in bold, and
the lag in frames (— where an approach's settings never get the jitter that low).
Standard library only."""
import csv
import os
import sys


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main(dirs):
    for d in dirs:
        study = rows(os.path.join(d, "smoothing.csv"))
        eq = rows(os.path.join(d, "smoothing_at_equal_jitter.csv"))
        none = next(r for r in study if r["approach"] == "none")
        j0 = float(none["jitter_target"])
        print(f"### {os.path.basename(d.rstrip('/'))}\n")
        print(
            f"unsmoothed: jitter {j0:.2f} px/frame², target RMS {float(none['target_rms_tracked']):.2f} (vs G(q)) / "
            f"{float(none['target_rms_clean']):.2f} (vs clean), source RMS {float(none['source_rms']):.3f}\n"
        )
        levels = sorted({r["jitter_target"] for r in eq}, key=lambda v: -float(v))[1:3]
        names = []
        for r in eq:
            if r["approach"] not in names:
                names.append(r["approach"])
        cell = {(r["approach"], r["jitter_target"]): r for r in eq}
        best = {}
        for lv in levels:
            for col in ("target_rms_tracked", "target_rms_clean"):
                here = [n for n in names if cell[(n, lv)][col]]
                if here:
                    best[(lv, col)] = min(here, key=lambda n: float(cell[(n, lv)][col]))
        head = " | ".join(
            f"{round(100 * float(lv) / j0)} % jitter: vs G(q) | vs clean | lag" for lv in levels
        )
        print(f"| approach | {head} |")
        print("|---" * (1 + 3 * len(levels)) + "|")
        for n in names:
            parts = []
            for lv in levels:
                r = cell[(n, lv)]
                for col in ("target_rms_tracked", "target_rms_clean"):
                    v = r[col]
                    txt = f"{float(v):.2f}" if v else "—"
                    if best.get((lv, col)) == n:
                        txt = f"**{txt}**"
                    parts.append(txt)
                parts.append(r["lag_frames"] or "—")
            print(f"| {n} | " + " | ".join(parts) + " |")
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
