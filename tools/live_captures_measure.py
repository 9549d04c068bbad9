#!/usr/bin/env python3
"""What the tracker's confidences change on real OpenSeeFace datagrams.

Replays each capture in ../shared/data/openseeface_captures through `kslab live --from
openseeface` (at 4x its recorded pacing) into a take, then solves the take with
`kslab rig --live` twice: as recorded (each point weighed by its confidence, an untracked
pupil left out) and with the confidence columns removed (every point alike, an untracked
pupil at its eye's centre, as before). Prints, per capture and way:

- the RMS landmark error (over the points the solve sees);
- jawOpen against the inner-lip gap, and the smiles against the mouth's width (Pearson r,
  the take's own geometry: there is no truth for a real video);
- for the gaze-off capture, the largest mean |difference| from the gaze-on capture's
  weights over the shapes that are not eyeLook*.

Usage: python3 tools/live_captures_measure.py [path/to/kslab]   (numpy needed)
"""
import csv
import io
import json
import os
import socket
import struct
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KSLAB = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target/release/kslab")
CAPS = os.path.join(ROOT, "..", "shared", "data", "openseeface_captures")


def records(path):
    b = open(path, "rb").read()
    o, out = 0, []
    while o < len(b):
        t, = struct.unpack_from("<d", b, o)
        n, = struct.unpack_from("<I", b, o + 8)
        out.append((t, b[o + 12:o + 12 + n]))
        o += 12 + n
    return out


def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def take_of(capture, take):
    recs = records(os.path.join(CAPS, capture))
    port = free_port()
    live = subprocess.Popen(
        [KSLAB, "live", "--from", f"openseeface:127.0.0.1:{port}", "--to", "stdout",
         "--queue", "1024", "--record", take],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
    time.sleep(1.0)
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    t0, start = recs[0][0], time.monotonic()
    for t, d in recs:
        due = start + (t - t0) / 4.0
        wait = due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        s.sendto(d, ("127.0.0.1", port))
    time.sleep(2.0)
    live.send_signal(2)
    live.wait(30)


def solve(track, extra=()):
    r = subprocess.run([KSLAB, "rig", track, "--live", "--json", *extra],
                       capture_output=True, text=True, check=True)
    return json.loads(r.stdout)


def weights(track, extra=()):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "w.csv")
        subprocess.run([KSLAB, "rig", track, "--live", "--out", out, *extra],
                       capture_output=True, text=True, check=True)
        rows = list(csv.reader(open(out)))
    return rows[0][1:], np.array([[float(v) for v in r[1:]] for r in rows[1:]])


def without_confidence(track, out):
    rows = list(csv.reader(open(track)))
    keep = [i for i, h in enumerate(rows[0]) if not (h.startswith("c") and h[1:].isdigit())]
    with open(out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        for r in rows:
            w.writerow([r[i] for i in keep])


def geometry(track):
    rows = list(csv.reader(open(track)))
    h = rows[0]
    xy = np.array([[float(v) for v in r[2:2 + 140]] for r in rows[1:]]).reshape(-1, 70, 2)
    iod = np.linalg.norm(xy[:, 36] - xy[:, 45], axis=1)
    gap = np.linalg.norm(xy[:, 62] - xy[:, 66], axis=1) / iod
    width = np.linalg.norm(xy[:, 60] - xy[:, 64], axis=1) / iod
    return gap, width


def main():
    with tempfile.TemporaryDirectory() as d:
        got = {}
        for cap in ["liveportrait_d14.osfcap", "liveportrait_d11.osfcap",
                    "liveportrait_d11_nogaze.osfcap"]:
            take = os.path.join(d, cap)
            take_of(cap, take)
            track = os.path.join(take, "track.csv")
            plain = os.path.join(d, cap + ".plain.csv")
            without_confidence(track, plain)
            gap, width = geometry(track)
            for way, t in [("confidence", track), ("every point alike", plain)]:
                s = solve(t)
                names, w = weights(t)
                jaw = w[:, names.index("jawOpen")]
                smile = w[:, names.index("mouthSmile_L")] + w[:, names.index("mouthSmile_R")]
                got[(cap, way)] = (names, w)
                print(f"{cap:34s} {way:18s} RMS {s['mean_rms']:.3f} px · "
                      f"jawOpen~gap r {np.corrcoef(jaw, gap)[0, 1]:.3f} · "
                      f"smiles~width r {np.corrcoef(smile, width)[0, 1]:.3f}")
        for way in ["confidence", "every point alike"]:
            names, on = got[("liveportrait_d11.osfcap", way)]
            _, off = got[("liveportrait_d11_nogaze.osfcap", way)]
            n = min(len(on), len(off))
            diff = np.abs(on[:n] - off[:n]).mean(axis=0)
            other = [(diff[i], names[i]) for i in range(len(names)) if not names[i].startswith("eyeLook")]
            eye = [diff[i] for i in range(len(names)) if names[i].startswith("eyeLook")]
            worst = max(other)
            print(f"gaze off against on, {way:18s}: non-eyeLook mean |Δ| worst {worst[0]:.4f} "
                  f"({worst[1]}), eyeLook mean |Δ| {np.mean(eye):.4f}")


if __name__ == "__main__":
    main()
