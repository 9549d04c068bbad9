#!/usr/bin/env python3
"""Would a quick preview of the lab's rig view show the right weights?

The rig issue (part 6) asked for the current frame's solve within 200 ms, before the
neutral search over the whole take. The only quick solves are the rig with no identity, or
a neutral searched among a few frames. This script measures the second: for six frames of
each track, the track cut to N evenly spaced frames plus that frame is solved by
`kslab rig` (its own neutral search among them, no zero-phase smoothing), and that frame's
weights are compared with the whole track's solve (no zero-phase smoothing either).

    python3 tools/rig_preview_check.py [--kslab target/release/kslab] [--samples 16] TRACK...

Prints, per frame: the largest |difference| of any shape's weight (and which shape), the
mean over the shapes, and the wall time of the preview's `kslab rig` (reading the rig and
the track included). Needs numpy.
"""
import argparse
import csv
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np


def read(p):
    rows = list(csv.reader(open(p)))
    return rows[0], rows[1:]


def weights(p):
    head, rows = read(p)
    return head, np.array([[float(x) for x in r[1:]] for r in rows])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--kslab", default="target/release/kslab")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("tracks", nargs="+")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp())
    for t in a.tracks:
        head, rows = read(t)
        full = tmp / "full.csv"
        subprocess.run([a.kslab, "rig", t, "-q", "--zero-phase", "0", "--out", full],
                       check=True, capture_output=True)
        names, w = weights(full)
        n = len(rows)
        out = []
        for f in np.linspace(0, n - 1, 6).astype(int):
            keep = sorted(set(np.linspace(0, n - 1, a.samples).astype(int).tolist()) | {int(f)})
            sub = tmp / "sub.csv"
            with open(sub, "w", newline="") as o:
                wr = csv.writer(o)
                wr.writerow(head)
                for i, k in enumerate(keep):
                    # Frames renumbered 0.. so the cut track reads as one clip.
                    wr.writerow([str(i)] + rows[k][1:])
            t0 = time.time()
            subw = tmp / "sub_w.csv"
            subprocess.run([a.kslab, "rig", sub, "-q", "--zero-phase", "0", "--out", subw],
                           check=True, capture_output=True)
            dt = time.time() - t0
            _, sw = weights(subw)
            d = np.abs(sw[keep.index(int(f))] - w[f])
            out.append(f"frame {f}: max {d.max():.2f} ({names[1 + int(d.argmax())]}) "
                       f"mean {d.mean():.3f}, {dt * 1000:.0f} ms")
        print(Path(t).name, "·", " · ".join(out))


if __name__ == "__main__":
    main()
