"""Derive the built-in default sequence embedded in `kslab`.

Source: ../shared/data/mediapipe_face_tracks/liveportrait_d18.csv (MediaPipe Face Mesh
468-point track of KwaiVGI/LivePortrait assets/examples/driving/d18.mp4, MIT; tracked
for this project, see that folder's README). Kept: every frame (216 at 30 fps), the 2-D
image coordinates x, y rounded to 0.1 px; dropped: the network depth z. Written in the
lab's plain CSV format (frame,time_s,x0,y0,...,x467,y467) and gzip-compressed.

Usage: python3 tools/make_builtin.py ../shared/data/mediapipe_face_tracks/liveportrait_d18.csv assets/builtin_d18.csv.gz
Standard library only; re-running gives the same bytes (mtime fixed at 0).
"""
import csv
import gzip
import io
import sys


def main(src, dst):
    with open(src, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    xi = [head.index(f"x_{i}") for i in range(468)]
    yi = [head.index(f"y_{i}") for i in range(468)]
    fi, ti, di = head.index("frame"), head.index("time_s"), head.index("detected")
    out = io.StringIO()
    out.write("frame,time_s," + ",".join(f"x{i},y{i}" for i in range(468)) + "\n")
    for row in body:
        if row[di] != "1":
            continue
        cells = []
        for a, b in zip(xi, yi):
            cells.append(f"{float(row[a]):.1f}")
            cells.append(f"{float(row[b]):.1f}")
        out.write(f"{row[fi]},{float(row[ti]):.4f}," + ",".join(cells) + "\n")
    data = out.getvalue().encode()
    with open(dst, "wb") as f:
        f.write(gzip.compress(data, compresslevel=9, mtime=0))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
