#!/usr/bin/env python3
"""Checks every relative link of the README and the book (docs/src/*.md): the file exists,
and a #fragment names a heading of the target Markdown file (ids as mdBook and GitHub make
them: lower case, spaces to '-', punctuation dropped, repeats numbered -1, -2 …). Links to
the web are left alone. Exits 1 listing every broken link. Usage: tools/check_links.py"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINK = re.compile(r"!?\[([^\]]*)\]\(([^)\s]+)\)")


def slug(heading):
    out = ""
    for ch in heading.strip().lower():
        if ch.isalnum() or ch in "_-":
            out += ch
        elif ch.isspace():
            out += "-"
    return out


def outside_code(text):
    """The lines of a Markdown file outside fenced code blocks, with inline code removed."""
    fenced = False
    for number, line in enumerate(text.split("\n"), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if not fenced:
            yield number, re.sub(r"`[^`]*`", "", line)


def anchors(path):
    seen, ids = {}, set()
    with open(path, encoding="utf-8") as f:
        for _, line in outside_code(f.read()):
            m = re.match(r"^#{1,6} (.*)", line)
            if m:
                s = slug(m.group(1))
                if s in seen:
                    seen[s] += 1
                    s = f"{s}-{seen[s]}"
                else:
                    seen[s] = 0
                ids.add(s)
    return ids


def main():
    files = [os.path.join(ROOT, "README.md")]
    book = os.path.join(ROOT, "docs", "src")
    files += sorted(os.path.join(book, f) for f in os.listdir(book) if f.endswith(".md"))
    broken, checked = [], 0
    for path in files:
        with open(path, encoding="utf-8") as f:
            text = f.read()
        for number, line in outside_code(text):
            for m in LINK.finditer(line):
                target = m.group(2)
                if re.match(r"^[a-z]+:", target):
                    continue
                checked += 1
                file_part, _, frag = target.partition("#")
                dest = os.path.normpath(os.path.join(os.path.dirname(path), file_part)) if file_part else path
                where = f"{os.path.relpath(path, ROOT)}:{number}: {target}"
                if not os.path.exists(dest):
                    broken.append(f"{where}: no such file")
                elif frag and dest.endswith(".md") and frag not in anchors(dest):
                    broken.append(f"{where}: no heading with id '{frag}'")
    for b in broken:
        print(b, file=sys.stderr)
    print(f"{checked} links checked in {len(files)} files, {len(broken)} broken")
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
