#!/usr/bin/env python3
"""Derives the MediaPipe Face Mesh 468 -> iBUG 68 correspondence kslab rig uses for 468-point
tracks (assets/features/mediapipe468_to_ibug68.json). Needs numpy; run from the repository:

    python3 tools/make_mediapipe_to_ibug68.py > assets/features/mediapipe468_to_ibug68.json

How: MediaPipe's canonical face (../shared/data/mediapipe_canonical_face, vertex i =
landmark i) is aligned to the ICT FaceKit neutral (../shared/data/ict_facekit_face) by a
similarity fitted on six points both name unambiguously (outer eye corners, mouth corners,
nose tip, chin: MediaPipe 33, 263, 61, 291, 1, 152 = iBUG 36, 45, 48, 54, 30, 8); then each
of the 68 ICT landmark vertices takes the nearest canonical vertex in the frontal (x, y)
plane, among the MediaPipe points of the same part (jaw -> face oval, brows -> brows, eyes
-> eyes, nose -> nose, lips -> lips; the layout's groups), so a jaw point cannot land on a
cheek. It is a geometric derivation from two neutral faces, not a published table: expect
errors of a few millimetres, largest on the jaw line (iBUG's jaw is a 2-D silhouette).
"""
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT / "../shared/data"


def obj_vertices(path):
    out = []
    for line in open(path):
        if line.startswith("v "):
            out.append([float(x) for x in line.split()[1:4]])
    return np.array(out)


def main():
    canon = obj_vertices(SHARED / "mediapipe_canonical_face/canonical_face_model.obj")
    ict = obj_vertices(SHARED / "ict_facekit_face/neutral_face.obj")
    marks = [int(l.split(",")[1]) for l in open(SHARED / "ict_facekit_face/landmarks_multipie68.csv").read().split("\n")[1:] if l.strip()]
    target = ict[marks]  # 68 x 3, cm
    anchors_mp = [33, 263, 61, 291, 1, 152]
    anchors_ib = [36, 45, 48, 54, 30, 8]
    a, b = canon[anchors_mp], target[anchors_ib]
    ma, mb = a.mean(0), b.mean(0)
    u, s, vt = np.linalg.svd((b - mb).T @ (a - ma))
    d = np.sign(np.linalg.det(u @ vt))
    r = u @ np.diag([1, 1, d]) @ vt
    scale = s.sum() / ((a - ma) ** 2).sum() if d > 0 else (s[0] + s[1] - s[2]) / ((a - ma) ** 2).sum()
    mapped = (canon - ma) @ r.T * scale + mb
    layout = json.load(open(ROOT / "assets/layout_mediapipe468.json"))["groups"]
    def halves(loop):
        """A closed polyline's two corners (x extremes) and its upper and lower halves."""
        pts = loop[:-1] if loop[0] == loop[-1] else loop
        xs = [mapped[p, 0] for p in pts]
        a, b = int(np.argmin(xs)), int(np.argmax(xs))
        if a > b:
            a, b = b, a
        one, two = pts[a + 1 : b], pts[b + 1 :] + pts[:a]
        up = lambda h: np.mean([mapped[p, 1] for p in h]) if h else 0.0
        upper, lower = (one, two) if up(one) > up(two) else (two, one)
        left, right = sorted([pts[a], pts[b]], key=lambda p: mapped[p, 0])
        return left, right, upper, lower

    g = layout
    lips_outer, lips_inner = g["lips"]["polylines"][0], g["lips"]["polylines"][1]
    out, err = [None] * 68, [None] * 68

    def nearest(i, cand):
        cand = sorted(set(cand))
        dist = np.linalg.norm(mapped[cand, :2] - target[i, :2], axis=1)
        j = int(np.argmin(dist))
        out[i], err[i] = cand[j], float(dist[j])

    def fix(i, p):
        out[i], err[i] = p, float(np.linalg.norm(mapped[p, :2] - target[i, :2]))

    for i in range(0, 17):
        nearest(i, g["face_oval"]["points"])
    for i in range(17, 22):
        nearest(i, g["right_eyebrow"]["points"])
    for i in range(22, 27):
        nearest(i, g["left_eyebrow"]["points"])
    for i in range(27, 36):
        nearest(i, g["nose"]["points"] + [1, 4, 5, 195, 197, 6, 168])
    # Closed contours: corners to the contour's x extremes, lids and lips half by half
    # (a neutral face's closed lips put the inner upper and lower lip on the same points).
    # Subject's right (iBUG 36-41) is image left: the smaller x in the canonical face.
    for (corner_a, upper_i, corner_b, lower_i), loop in [
        ((36, [37, 38], 39, [40, 41]), g["right_eye"]["polylines"][0]),
        ((42, [43, 44], 45, [46, 47]), g["left_eye"]["polylines"][0]),
        ((48, [49, 50, 51, 52, 53], 54, [55, 56, 57, 58, 59]), lips_outer),
        ((60, [61, 62, 63], 64, [65, 66, 67]), lips_inner),
    ]:
        left, right, upper, lower = halves(loop)
        ca, cb = (left, right) if target[corner_a, 0] < target[corner_b, 0] else (right, left)
        fix(corner_a, ca)
        fix(corner_b, cb)
        for i in upper_i:
            nearest(i, upper)
        for i in lower_i:
            nearest(i, lower)
    anchor_rms = float(np.sqrt(((mapped[anchors_mp] - b) ** 2).sum(1).mean()))
    doc = {
        "kslab_correspondence": 1,
        "from": "mediapipe_face_mesh_468",
        "to": "ibug68",
        "description": "For each iBUG-68 landmark (0-67), the MediaPipe Face Mesh landmark kslab rig reads in its place. Derived by tools/make_mediapipe_to_ibug68.py: MediaPipe's canonical face aligned to the ICT FaceKit neutral by a similarity on six anchors (MediaPipe 33, 263, 61, 291, 1, 152 = iBUG 36, 45, 48, 54, 30, 8), then the nearest canonical vertex of the same part in the frontal plane. A geometric derivation from two neutral faces, not a published table.",
        "anchor_rms_cm": round(anchor_rms, 3),
        "max_frontal_distance_cm": round(max(err), 3),
        "mediapipe": out,
    }
    json.dump(doc, sys.stdout, indent=1)
    print()
    print(f"anchor RMS {anchor_rms:.3f} cm, frontal distance max {max(err):.3f} cm, mean {np.mean(err):.3f} cm", file=sys.stderr)


if __name__ == "__main__":
    main()
