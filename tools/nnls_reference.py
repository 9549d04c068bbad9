"""Reference NNLS solutions from SciPy (an independent Lawson-Hanson implementation) for
tests/it/reference.rs. Run from the repository root with ../shared beside it:

    pip install numpy scipy && python3 tools/nnls_reference.py > tests/data/nnls_reference.json

Problems: seeded random "shape-like" bases (a shared base shape plus offsets, like real key
shapes), one with a duplicated key shape, and one on the real lip contours of
liveportrait_d18 (raw image coordinates, no alignment, so no Procrustes is needed here).
"""
import csv
import json
import sys

import numpy as np
import scipy
from scipy.optimize import nnls


def shape_like(rng, n, k, frames, dup=False):
    base = rng.uniform(-1, 1, n) * 10
    s = base[:, None] + rng.uniform(-1, 1, (n, k))
    if dup:
        s[:, -1] = s[:, 0]
    w = rng.uniform(-0.5, 1.5, (k, frames))
    q = s @ w + rng.normal(0, 0.05, (n, frames))
    return s, q


def real_lips():
    layout = json.load(open("../shared/data/mediapipe_face_tracks/layout_mediapipe468.json"))
    lips = sorted(layout["groups"]["lips"]["points"])
    rows = list(csv.reader(open("../shared/data/mediapipe_face_tracks/liveportrait_d18.csv")))
    head, body = rows[0], rows[1:]
    cols = []
    for p in lips:
        cols += [head.index(f"x_{p}"), head.index(f"y_{p}")]
    q_all = np.array([[float(r[c]) for c in cols] for r in body]).T
    keys = [0, 40, 80, 120, 160, 200, 215]
    frames = [10, 50, 100, 150, 190]
    return q_all[:, keys], q_all[:, frames], lips, keys, frames


def main():
    rng = np.random.default_rng(20261123)
    out = {"scipy": scipy.__version__, "numpy": np.__version__, "problems": []}
    for n, k, frames, dup in [(24, 4, 3, False), (40, 8, 3, False), (80, 16, 3, False), (30, 6, 3, True)]:
        s, q = shape_like(rng, n, k, frames, dup)
        sols = [nnls(s, q[:, j], maxiter=10 * k) for j in range(frames)]
        out["problems"].append({
            "name": f"random n={n} k={k}" + (" duplicate column" if dup else ""),
            "s": s.T.tolist(), "q": q.T.tolist(),
            "w": [w.tolist() for w, _ in sols], "residual": [r for _, r in sols],
        })
    s, q, lips, keys, frames = real_lips()
    sols = [nnls(s, q[:, j]) for j in range(q.shape[1])]
    out["real"] = {
        "file": "mediapipe_face_tracks/liveportrait_d18.csv", "points": lips,
        "keys": keys, "frames": frames,
        "w": [w.tolist() for w, _ in sols], "residual": [r for _, r in sols],
    }
    json.dump(out, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
