#!/usr/bin/env python3
"""Prints the README's cross-person tables from the corpus experiments' reports:
    for f in experiments/corpus_*.toml; do kslab run -q "$f"; done
    python3 tools/corpus_summary.py
Standard library only."""
import csv
import os

CORPORA = [
    ("corpus_fig6_lips_mediapipe", "MediaPipe lips (4)", [4, 12, 24]),
    ("corpus_fig6_face_mediapipe", "MediaPipe face (4)", [4, 12, 24]),
    ("corpus_fig6_lips_ibug68", "iBUG-68 lips (21)", [4, 8, 12]),
    ("corpus_fig6_face_ibug68", "iBUG-68 face (21)", [4, 8, 12]),
]
METHODS = ["spread", "kmeans2-mean", "kmeans2", "greedy", "random"]


def rows(d, f):
    p = os.path.join("out", d, f)
    return list(csv.DictReader(open(p))) if os.path.exists(p) else []


def ci(r, m="mean_rms_iod", lo="lo95", hi="hi95", scale=100):
    return f"{float(r[m]) * scale:.2f} ({float(r[lo]) * scale:.2f}–{float(r[hi]) * scale:.2f})"


print("Mean RMS per point in % of IOD (bootstrap 95 % interval over sequences)\n")
print("| corpus | solver | k | " + " | ".join(METHODS) + " |")
print("|---|---|---|" + "---|" * len(METHODS))
for d, name, ks in CORPORA:
    s = rows(d, "corpus_summary.csv")
    for solver in ["nnls", "ls"]:
        for k in ks:
            cells = []
            for m in METHODS:
                r = [x for x in s if x["method"] == m and x["solver"] == solver and x["k"] == str(k)]
                cells.append(ci(r[0]) if r else "")
            print(f"| {name} | {solver} | {k} | " + " | ".join(cells) + " |")

print("\nWins over all (sequence, k), and paired differences in % IOD (a − b; a lower on n of N)\n")
print("| corpus | solver | wins: spread / kmeans2-mean / kmeans3-mean / greedy / others | greedy − spread, k=8 | kmeans2-mean − spread, k=8 | hull at its own k − spread there |")
print("|---|---|---|---|---|---|")
for d, name, ks in CORPORA:
    w = rows(d, "corpus_wins.csv")
    p = rows(d, "corpus_paired.csv")
    own = rows(d, "corpus_own_k.csv")
    for solver in ["nnls", "ls"]:
        ww = {x["method"]: int(x["wins"]) for x in w if x["solver"] == solver}
        contests = next(int(x["contests"]) for x in w if x["solver"] == solver)
        others = sum(v for m, v in ww.items() if m not in ("spread", "kmeans2-mean", "kmeans3-mean", "greedy"))
        wins = f"{ww.get('spread', 0)} / {ww.get('kmeans2-mean', 0)} / {ww.get('kmeans3-mean', 0)} / {ww.get('greedy', 0)} / {others} of {contests}"

        def pair(a, b, k=8):
            for x in p:
                if x["solver"] == solver and x["k"] == str(k):
                    n = x["sequences"]
                    if (x["method_a"], x["method_b"]) == (a, b):
                        return f"{ci(x, 'mean_diff_iod')}; {x['a_lower']}/{n}"
                    if (x["method_a"], x["method_b"]) == (b, a):
                        # b − a flipped
                        m, lo, hi = (-float(x[c]) * 100 for c in ("mean_diff_iod", "hi95", "lo95"))
                        return f"{m:.2f} ({lo:.2f}–{hi:.2f}); {x['b_lower']}/{n}"
            return ""

        h = [x for x in own if x["solver"] == solver and x["compared_with"] == "spread"]
        hull = ""
        if h:
            x = h[0]
            m, lo, hi = (-float(x[c]) * 100 for c in ("mean_diff_iod", "diff_hi95", "diff_lo95"))
            n = int(x["compared_sequences"])
            hull = f"{m:.2f} ({lo:.2f}–{hi:.2f}); hull lower on {n - int(x['other_lower'])}/{n}, mean k {float(x['mean_k']):.1f}"
        elif own:
            x = [x for x in own if x["solver"] == solver][0]
            hull = f"mean k {float(x['mean_k']):.1f}, beyond the range"
        print(f"| {name} | {solver} | {wins} | {pair('greedy', 'spread')} | {pair('kmeans2-mean', 'spread')} | {hull} |")

print("\nFigs. 4-5 across people: target-domain RMS, LS − NNLS, % IOD (LS lower on n of N)\n")
print("| corpus | noise 0 | 0.5 % | 1 % | 2 % |")
print("|---|---|---|---|---|")
for d, name, _ in CORPORA:
    rp = rows(d, "corpus_retarget_paired.csv")
    if not rp:
        continue
    cells = [f"{ci(x, 'mean_target_diff_iod')}; {x['a_lower_target']}/{x['sequences']}" for x in rp]
    print(f"| {name} | " + " | ".join(cells) + " |")
