#!/usr/bin/env python3
"""The house's size limits, run by CI: no Rust source under `src/` or `crates/*/src/` over
600 lines, and no function outside `#[cfg(test)]` modules over 100 lines (a long function
is cut into steps a reader can name). Prints each offender and exits 1 when there is one.

Functions are found by a brace count that blanks string and character literals and `//`
comments first; a raw string holding braces would confuse it (none does today)."""
import re
import subprocess
import sys

MAX_FILE = 600
MAX_FN = 100
FN = re.compile(r"\s*(pub(\([a-z]+\))? )?(const )?(async )?(unsafe )?fn (\w+)")


def code(line):
    """`line` with string and char literals and a `//` comment blanked."""
    line = re.sub(r'"([^"\\]|\\.)*"', '""', line)
    line = re.sub(r"'([^'\\]|\\.)'", "''", line)
    return line.split("//")[0]


def long_functions(path, lines):
    out = []
    in_test = False
    for n, line in enumerate(lines):
        s = line.strip()
        if s.startswith("#[cfg(test)]"):
            # Test modules come last in this workspace's files.
            in_test = True
        m = FN.match(line)
        if not m or in_test or s.startswith("//"):
            continue
        depth, started = 0, False
        for k in range(n, len(lines)):
            t = code(lines[k])
            if not started and ";" in t and "{" not in t:
                break  # a declaration (trait method without a body)
            depth += t.count("{") - t.count("}")
            started |= "{" in t
            if started and depth <= 0:
                if k - n + 1 > MAX_FN:
                    out.append(f"{path}:{n + 1}: fn {m.group(6)} is {k - n + 1} lines (limit {MAX_FN})")
                break
    return out


def main():
    files = subprocess.check_output(
        ["git", "ls-files", "src/*.rs", "crates/*/src/*.rs", "crates/*/src/**/*.rs"], text=True
    ).split()
    bad = []
    for f in sorted(set(files)):
        lines = open(f, encoding="utf-8").read().split("\n")
        if len(lines) - 1 > MAX_FILE:
            bad.append(f"{f}: {len(lines) - 1} lines (limit {MAX_FILE})")
        bad += long_functions(f, lines)
    for b in bad:
        print(b)
    print(f"{len(files)} sources checked: {len(bad)} over the limits", file=sys.stderr)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
