"""Summarise the Fig. 6 experiments for the README (standard library only).

    for f in experiments/chuang_fig6_*.toml; do kslab run -q "$f"; done
    python3 tools/fig6_summary.py            # reads out/chuang_fig6_*/curves.csv
"""
import csv
import glob
import os

PAPER = ["spread", "kmeans2", "kmeans3"]


def main():
    print("| experiment | solver | spread RMS k=8 / 16 / 24 | best k-means k=8 / 16 / 24 | greedy k=8 / 16 / 24 | random k=8 / 16 / 24 | spread lowest of the paper's methods | k-means curve rises | greedy below spread | hull: k, RMS (spread at that k) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in sorted(glob.glob("out/chuang_fig6_*")):
        rows = list(csv.DictReader(open(os.path.join(d, "curves.csv"))))
        for solver in ["nnls", "ls"]:
            r = {(x["method"], int(x["k"])): float(x["rms"]) for x in rows if x["solver"] == solver}
            ks = range(2, 25)
            f = lambda m: " / ".join(f"{r[(m, k)]:.2f}" for k in (8, 16, 24))
            best_km = " / ".join(f"{min(r[('kmeans2', k)], r[('kmeans3', k)]):.2f}" for k in (8, 16, 24))
            lowest = sum(r[("spread", k)] <= min(r[(m, k)] for m in PAPER) for k in ks)
            rises = sum(r[(m, k + 1)] > r[(m, k)] for m in ("kmeans2", "kmeans3") for k in range(2, 24))
            greedy = sum(r[("greedy", k)] < r[("spread", k)] for k in ks)
            hull = [(k, v) for (m, k), v in r.items() if m == "hull"][0]
            sp = r.get(("spread", hull[0]))
            sp = f"{sp:.2f}" if sp is not None else "–"
            name = os.path.basename(d).replace("chuang_fig6_", "")
            print(f"| {name} | {solver} | {f('spread')} | {best_km} | {f('greedy')} | {f('random')} | {lowest}/23 | {rises}/44 steps | {greedy}/23 | {hull[0]}, {hull[1]:.2f} ({sp}) |")


if __name__ == "__main__":
    main()
