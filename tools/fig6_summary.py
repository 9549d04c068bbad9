"""Summarise the Fig. 6 experiments for the README (standard library only).

    for f in experiments/chuang_fig6_*.toml; do kslab run -q "$f"; done
    python3 tools/fig6_summary.py            # reads out/chuang_fig6_*/curves.csv, curves_raw.csv

Table 1: aligned coordinates (head motion removed). The paper's k-means key shape is the
cluster's centre of mass (`kmeansN-mean`); `kmeansN` (the frame nearest the centre) is ours.
Table 2: the same sweeps on raw coordinates beside the aligned ones.
"""
import csv
import glob
import os

KS = range(2, 25)


def load(path, solver):
    rows = list(csv.DictReader(open(path)))
    return {(x["method"], int(x["k"])): float(x["rms"]) for x in rows if x["solver"] == solver}


def best(r, methods, k):
    return min(r[(m, k)] for m in methods)


def three(f):
    return " / ".join(f"{f(k):.2f}" for k in (8, 16, 24))


def main():
    means = ["kmeans2-mean", "kmeans3-mean"]
    frames = ["kmeans2", "kmeans3"]
    print("| experiment | solver | spread k=8 / 16 / 24 | k-means centre of mass (paper) | k-means nearest frame (ours) | greedy | random | spread lowest of spread and the paper's k-means | centre of mass below nearest frame | greedy below spread | hull: k, RMS (spread at that k) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    dirs = sorted(glob.glob("out/chuang_fig6_*"))
    for d in dirs:
        name = os.path.basename(d).replace("chuang_fig6_", "")
        for solver in ["nnls", "ls"]:
            r = load(os.path.join(d, "curves.csv"), solver)
            lowest = sum(r[("spread", k)] <= best(r, means, k) for k in KS)
            mean_wins = sum(best(r, means, k) < best(r, frames, k) for k in KS)
            greedy = sum(r[("greedy", k)] < r[("spread", k)] for k in KS)
            hull = [(k, v) for (m, k), v in r.items() if m == "hull"][0]
            sp = r.get(("spread", hull[0]))
            sp = f"{sp:.2f}" if sp is not None else "–"
            print(f"| {name} | {solver} | {three(lambda k: r[('spread', k)])} | {three(lambda k: best(r, means, k))} | {three(lambda k: best(r, frames, k))} | {three(lambda k: r[('greedy', k)])} | {three(lambda k: r[('random', k)])} | {lowest}/23 | {mean_wins}/23 | {greedy}/23 | {hull[0]}, {hull[1]:.2f} ({sp}) |")
    print()
    print("| experiment | solver | spread aligned / raw, k=8 / 16 / 24 | random aligned / raw, k=8 / 16 / 24 | raw: spread worse than random | raw: spread lowest of spread and the paper's k-means | aligned: the same |")
    print("|---|---|---|---|---|---|---|")
    for d in dirs:
        name = os.path.basename(d).replace("chuang_fig6_", "")
        raw_path = os.path.join(d, "curves_raw.csv")
        if not os.path.exists(raw_path):
            continue
        for solver in ["nnls", "ls"]:
            a = load(os.path.join(d, "curves.csv"), solver)
            r = load(raw_path, solver)
            pair = lambda m: " / ".join(f"{a[(m, k)]:.2f}→{r[(m, k)]:.2f}" for k in (8, 16, 24))
            worse = [k for k in KS if r[("spread", k)] > r[("random", k)]]
            lowest_raw = sum(r[("spread", k)] <= best(r, means, k) for k in KS)
            lowest = sum(a[("spread", k)] <= best(a, means, k) for k in KS)
            w = f"{len(worse)}/23" + (f" (between k = {worse[0]} and {worse[-1]})" if worse else "")
            print(f"| {name} | {solver} | {pair('spread')} | {pair('random')} | {w} | {lowest_raw}/23 | {lowest}/23 |")


if __name__ == "__main__":
    main()
