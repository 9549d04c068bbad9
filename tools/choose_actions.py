"""Choose example frames for Cosker-style actions on a MediaPipe track (standard library).

Each action's example is the frame where a simple geometric measure (normalised by the
inter-ocular distance, so head distance does not matter) is extreme:
  jaw_drop        max inner-lip gap |p13 - p14|
  smile           max mouth width |p61 - p291|
  pucker          min mouth width
  brow_raise_L/R  max brow-to-eye height (brow centroid above eye centroid)
  brow_lower_L/R  min brow-to-eye height
  eyes_wide       max mean eyelid gap (|p159 - p145| + |p386 - p374|) / 2
  blink           min mean eyelid gap
Usage: python3 tools/choose_actions.py ../shared/data/mediapipe_face_tracks/liveportrait_d6.csv > assets/actions/actions_liveportrait_d6.json
"""
import csv
import json
import math
import sys

L_BROW = [276, 283, 282, 295, 285, 300, 293, 334, 296, 336]
R_BROW = [46, 53, 52, 65, 55, 70, 63, 105, 66, 107]
L_EYE = [263, 249, 390, 373, 374, 380, 381, 382, 362, 398, 384, 385, 386, 387, 388, 466]
R_EYE = [33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246]


def main(path):
    rows = [r for r in csv.DictReader(open(path)) if r["detected"] == "1"]
    def p(r, i):
        return float(r[f"x_{i}"]), float(r[f"y_{i}"])
    def d(a, b):
        return math.hypot(a[0] - b[0], a[1] - b[1])
    def cy(r, idx):
        return sum(p(r, i)[1] for i in idx) / len(idx)
    m = {k: [] for k in ["gap", "width", "lbrow", "rbrow", "lid"]}
    for r in rows:
        iod = d(p(r, 33), p(r, 263))
        m["gap"].append(d(p(r, 13), p(r, 14)) / iod)
        m["width"].append(d(p(r, 61), p(r, 291)) / iod)
        m["lbrow"].append((cy(r, L_EYE) - cy(r, L_BROW)) / iod)
        m["rbrow"].append((cy(r, R_EYE) - cy(r, R_BROW)) / iod)
        m["lid"].append((d(p(r, 159), p(r, 145)) + d(p(r, 386), p(r, 374))) / 2 / iod)
    frame = lambda k, f: int(rows[max(range(len(rows)), key=lambda i: f * m[k][i])]["frame"])
    acts = [("jaw_drop", "lower_face", frame("gap", 1)), ("smile", "lower_face", frame("width", 1)), ("pucker", "lower_face", frame("width", -1)),
            ("brow_raise_left", "left_brow", frame("lbrow", 1)), ("brow_lower_left", "left_brow", frame("lbrow", -1)),
            ("brow_raise_right", "right_brow", frame("rbrow", 1)), ("brow_lower_right", "right_brow", frame("rbrow", -1)),
            ("eyes_wide", "forehead", frame("lid", 1)), ("blink", "forehead", frame("lid", -1))]
    print(json.dumps({"kslab_actions": 1, "sequence": path.split("shared/data/")[-1],
                      "how_chosen": __doc__.split("Usage:")[0].strip(),
                      "actions": [{"name": n, "region": g, "frame": f} for n, g, f in acts]}, indent=1))


if __name__ == "__main__":
    main(sys.argv[1])
