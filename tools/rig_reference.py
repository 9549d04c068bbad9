#!/usr/bin/env python3
"""A small numpy/SciPy reference rig solver for `kslab rig-accuracy --tracks DIR`.

Per frame: a scaled-orthographic camera and bounded weights (0 <= w <= 1) with a ridge
mu * ||w||^2, fitted by alternation (camera by an SVD fit of the posed 3-D landmarks,
weights by scipy.optimize.lsq_linear on the augmented system [A; sqrt(mu) I]); the
identity is the mean 2-D residual of the lead-in frames, lifted into the rig at each
lead-in frame's camera (an offset of the rig's neutral landmarks). Optionally a zero-phase
Gaussian of sigma frames afterwards. Nothing of keyshape-lab's solver is used: it is the
yardstick the issue asks ours to be reported beside.

    python3 tools/rig_reference.py ../shared/data/ict_facekit_face DIR [--mu 30] [--lead-in 20] [--sigma 0]

prints, per kind in DIR, mean r / worst r over the active shapes, the weight RMSE and the
largest weight of an unused shape. mu is in px^2 (30 px^2 at an inter-ocular distance
of 107 px is kslab's default prior 0.0026 x IOD^2).
"""
import argparse
import csv
import glob
import os

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.optimize import lsq_linear


def read_rig(d, marks):
    """The rig's landmarks at `marks` (mesh vertices, one per landmark, in track order)."""
    n = len(marks)
    verts = [list(map(float, l.split()[1:4])) for l in open(os.path.join(d, "neutral_face.obj")) if l.startswith("v ")]
    neutral = np.array([verts[v] for v in marks])
    names = [r["shape"] for r in csv.DictReader(open(os.path.join(d, "expressions.csv")))]
    at = {v: i for i, v in enumerate(marks)}
    deltas = np.zeros((len(names), n, 3))
    for r in csv.DictReader(open(os.path.join(d, "expression_deltas.csv"))):
        v = int(r["vertex"])
        if v in at:
            deltas[int(r["shape_id"]), at[v]] = [float(r["dx"]), float(r["dy"]), float(r["dz"])]
    return names, neutral, deltas


def fit_camera(x, u):
    """Scaled orthographic camera u ~ s R[:2] x + t (x: n x 3, u: n x 2, y up)."""
    xc, uc = x - x.mean(0), u - u.mean(0)
    m, *_ = np.linalg.lstsq(xc, uc, rcond=None)  # 3x2 affine
    a = m.T  # 2x3
    uu, sv, vt = np.linalg.svd(a, full_matrices=False)
    r2 = uu @ vt
    s = sv.mean()
    t = u.mean(0) - s * (r2 @ x.mean(0))
    return s, r2, t


def solve_frame(u, neutral, deltas, mu, w0, iters=15):
    k = deltas.shape[0]
    w = w0.copy()
    for _ in range(iters):
        x = neutral + np.tensordot(w, deltas, 1)
        s, r2, t = fit_camera(x, u)
        a = np.stack([(s * deltas[j] @ r2.T).ravel() for j in range(k)], 1)
        b = (u - (s * neutral @ r2.T + t)).ravel()
        aug = np.vstack([a, np.sqrt(mu) * np.eye(k)])
        rhs = np.concatenate([b, np.zeros(k)])
        w = lsq_linear(aug, rhs, bounds=(0.0, 1.0), method="bvls").x
    return w, (s, r2, t)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("rig")
    p.add_argument("dir")
    p.add_argument("--mu", type=float, default=30.0)
    p.add_argument("--lead-in", type=int, default=20)
    p.add_argument("--sigma", type=float, default=0.0)
    p.add_argument(
        "--landmarks",
        help="landmark,vertex CSV naming the vertex of each track point (default: the rig's "
        "landmarks_multipie68.csv; for `rig-accuracy --landmarks 468` tracks, "
        "assets/features/mediapipe468_to_ict.csv)",
    )
    a = p.parse_args()
    marks_csv = a.landmarks or os.path.join(a.rig, "landmarks_multipie68.csv")
    vertex_of = {int(r["landmark"]): int(r["vertex"]) for r in csv.DictReader(open(marks_csv))}
    for path in sorted(glob.glob(os.path.join(a.dir, "*_track.csv"))):
        kind = os.path.basename(path)[: -len("_track.csv")]
        # The header names each landmark's track point: x0,y0,... (iBUG) or x33,y33,...
        header = open(path).readline().strip().split(",")[1:]
        points = [int(h[1:]) for h in header[0::2]]
        names, neutral, deltas = read_rig(a.rig, [vertex_of[q] for q in points])
        rows = np.loadtxt(path, delimiter=",", skiprows=1)[:, 1:]
        truth = np.loadtxt(os.path.join(a.dir, kind + "_truth.csv"), delimiter=",", skiprows=1)[:, 1:]
        track = rows.reshape(len(rows), len(points), 2) * [1.0, -1.0]  # y up
        # Identity from the lead-in: the mean residual of the rig's neutral, lifted.
        person = neutral.copy()
        if a.lead_in > 0:
            lift = np.zeros_like(neutral)
            for f in range(a.lead_in):
                s, r2, t = fit_camera(person, track[f])
                res = track[f] - (s * person @ r2.T + t)
                lift += (res @ r2) / s
            person = person + lift / a.lead_in
        k = len(names)
        w = np.zeros(k)
        out = np.zeros((len(track), k))
        for f in range(len(track)):
            w, _ = solve_frame(track[f], person, deltas, a.mu, w)
            out[f] = w
        if a.sigma > 0:
            out = gaussian_filter1d(out, a.sigma, axis=0, mode="nearest")
        act = [j for j in range(k) if truth[:, j].max() > 1e-9]
        rs = [np.corrcoef(out[:, j], truth[:, j])[0, 1] if out[:, j].std() > 0 else 0.0 for j in act]
        idle = max((out[:, j].max(), names[j]) for j in range(k) if j not in act)
        worst = min(zip(rs, [names[j] for j in act]))
        rmse = np.sqrt(((out - truth) ** 2).mean())
        print(f"{kind:<7} mean r {np.mean(rs):.3f}  worst r {worst[0]:.3f} ({worst[1]})  weight RMSE {rmse:.3f}  idle max {idle[0]:.2f} ({idle[1]})")


if __name__ == "__main__":
    main()
