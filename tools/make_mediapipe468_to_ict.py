#!/usr/bin/env python3
"""Derives the dense MediaPipe Face Mesh 468 -> ICT FaceKit correspondence kslab rig uses for
468- and 478-point tracks on the ICT rig (assets/features/mediapipe468_to_ict.csv, a
`landmark,vertex` CSV in the format a glTF rig's --rig-landmarks takes). Needs numpy and
scipy; run from the repository:

    python3 tools/make_mediapipe468_to_ict.py > assets/features/mediapipe468_to_ict.csv

How:
1. MediaPipe's canonical face (../shared/data/mediapipe_canonical_face, vertex i = landmark i)
   is aligned to the ICT neutral (../shared/data/ict_facekit_face) by a similarity fitted on
   the 68 pairs the sparse path already uses (assets/features/mediapipe468_to_ibug68.json:
   MediaPipe point -> iBUG landmark -> ICT's published vertex).
2. The aligned canonical face is warped onto the ICT face by a thin-plate-spline RBF through
   the same 68 pairs (smoothing 1 cm^2, so a pair that disagrees by a few millimetres bends
   the warp rather than tearing it): the two faces' proportions differ, and a similarity
   alone leaves the cheeks and jaw a centimetre off.
3. Each warped point takes the NEAREST ICT VERTEX in 3-D (not a point on a triangle: the
   rig's landmarks are then ordinary vertices, the solve's cost is the same as any vertex
   landmark, and the ICT face's vertex spacing, ~3 mm over the face, is below the
   derivation's own uncertainty). Candidates are the vertices on the front of the face
   (normal z > 0.2 after the alignment, so no point lands on an ear or inside a nostril)
   that are not already taken (two MediaPipe points never share a vertex; the nearer one
   wins, the other takes its next nearest).
4. A point whose nearest free vertex is further than 0.8 cm is left out (the rig does not
   cover it there): this drops none of the 468 on the ICT face, but the rule is there for
   rigs that cover less.

Checked on what it did not use: MediaPipe's canonical face is left/right symmetric, so a
mirror pair of MediaPipe points (i at x, j at -x) must land on ICT vertices that mirror each
other; stderr reports how far they miss (tests/it/rig_dense.rs checks the committed file).
"""
import json
import sys
from pathlib import Path

import numpy as np
from scipy.interpolate import RBFInterpolator
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT / "../shared/data"
MAX_CM = 0.8


def obj(path):
    v, f = [], []
    for line in open(path):
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            f.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    return np.array(v), f


def vertex_normals(v, faces):
    n = np.zeros_like(v)
    for f in faces:
        for a in range(1, len(f) - 1):
            p, q, r = v[f[0]], v[f[a]], v[f[a + 1]]
            c = np.cross(q - p, r - p)
            for i in (f[0], f[a], f[a + 1]):
                n[i] += c
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def main():
    canon, _ = obj(SHARED / "mediapipe_canonical_face/canonical_face_model.obj")
    ict, faces = obj(SHARED / "ict_facekit_face/neutral_face.obj")
    marks = [
        int(l.split(",")[1])
        for l in open(SHARED / "ict_facekit_face/landmarks_multipie68.csv").read().split("\n")[1:]
        if l.strip()
    ]
    mp68 = json.load(open(ROOT / "assets/features/mediapipe468_to_ibug68.json"))["mediapipe"]
    a, b = canon[mp68], ict[marks]
    ma, mb = a.mean(0), b.mean(0)
    u, s, vt = np.linalg.svd((b - mb).T @ (a - ma))
    d = np.sign(np.linalg.det(u @ vt))
    r = u @ np.diag([1, 1, d]) @ vt
    scale = (s[0] + s[1] + d * s[2]) / ((a - ma) ** 2).sum()
    aligned = (canon - ma) @ r.T * scale + mb
    warp = RBFInterpolator(aligned[mp68], b - aligned[mp68], kernel="thin_plate_spline", smoothing=1.0)
    warped = aligned + warp(aligned)

    normals = vertex_normals(ict, faces)
    front = np.where(normals[:, 2] > 0.2)[0]
    tree = cKDTree(ict[front])
    dist, idx = tree.query(warped, k=16)
    # Nearest first; a taken vertex passes the point on to its next nearest.
    order = np.argsort(dist[:, 0])
    taken, out, err = set(), [None] * len(canon), [None] * len(canon)
    for i in order:
        for dd, j in zip(dist[i], idx[i]):
            v = int(front[j])
            if v not in taken and dd <= MAX_CM:
                taken.add(v)
                out[i], err[i] = v, float(dd)
                break

    kept = [i for i in range(len(canon)) if out[i] is not None]
    print("landmark,vertex")
    for i in kept:
        print(f"{i},{out[i]}")

    e = np.array([err[i] for i in kept])
    mirror = canon * np.array([-1, 1, 1])
    mt = cKDTree(canon)
    md, mj = mt.query(mirror)
    miss = []
    for i in kept:
        j = int(mj[i])
        if md[i] < 0.05 and out[j] is not None and i != j:
            p, q = ict[out[i]], ict[out[j]] * np.array([-1, 1, 1])
            miss.append(np.linalg.norm(p - q))
    miss = np.array(miss)
    print(
        f"{len(kept)} of {len(canon)} kept; vertex distance mean {e.mean():.3f} cm, max {e.max():.3f} cm; "
        f"mirror pairs {len(miss)}: miss mean {miss.mean():.3f} cm, max {miss.max():.3f} cm",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
