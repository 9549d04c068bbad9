#!/usr/bin/env python3
"""Checks the workspace's layering (docs/src/where-things-live.md): each crate may depend
only on crates of a lower layer, so the papers' crates never use one another and nothing
uses the lab, the TUI or the binary. Reads `cargo metadata`; exits 1 naming every edge that
breaks the order. Usage: tools/check_layers.py"""
import json
import subprocess
import sys

LAYERS = {
    "keyshape-core": 0,
    "keyshape-io": 1,
    "keyshape-retarget": 2,
    "keyshape-actions": 2,
    "keyshape-transfer": 2,
    "keyshape-rig": 2,
    "keyshape-pictures": 2,
    "keyshape-experiments": 3,
    "keyshape-live": 3,
    "kslab-tui": 4,
    "keyshape-fuzz": 4,
    "kslab": 5,
}


def main():
    meta = json.loads(
        subprocess.check_output(["cargo", "metadata", "--format-version", "1", "--no-deps"])
    )
    bad, edges = [], 0
    members = {p["name"] for p in meta["packages"]}
    unknown = members - set(LAYERS)
    if unknown:
        bad.append(f"crates with no layer in tools/check_layers.py: {sorted(unknown)}")
    for p in meta["packages"]:
        if p["name"] not in LAYERS:
            continue  # reported above
        for d in p["dependencies"]:
            if d["name"] not in LAYERS or d.get("kind") == "dev":
                continue
            edges += 1
            if LAYERS[d["name"]] >= LAYERS[p["name"]]:
                bad.append(
                    f"{p['name']} (layer {LAYERS[p['name']]}) depends on {d['name']} (layer {LAYERS[d['name']]})"
                )
    for b in bad:
        print(b, file=sys.stderr)
    print(f"{edges} edges between the workspace's {len(members)} crates, {len(bad)} against the layers")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
