#!/usr/bin/env python3
"""Copies each generated table (docs/tables/NAME.md, written by docs/reproduce.sh) into README.md
and docs/*.md between the markers

    <!-- table NAME -->
    ...
    <!-- /table NAME -->

so that the documents show the numbers of the last run and no number is typed by hand. Prints what
it replaced; exits 1 when a marker names a table that does not exist or is not closed.

    python3 docs/figures/paste_tables.py [--check]

--check changes nothing and exits 1 when a document's block differs from its table."""
import glob, os, re, sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BLOCK = re.compile(r"(<!-- table ([A-Za-z0-9_-]+) -->\n)(.*?)(<!-- /table \2 -->)", re.S)


def main():
    check = "--check" in sys.argv[1:]
    status = 0
    for path in [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md"))):
        text = open(path).read()
        opened = re.findall(r"<!-- table ([A-Za-z0-9_-]+) -->", text)
        closed = re.findall(r"<!-- /table ([A-Za-z0-9_-]+) -->", text)
        if sorted(opened) != sorted(closed):
            print("%s: a table marker is not closed (%s)" % (os.path.relpath(path, ROOT), sorted(set(opened) ^ set(closed))))
            status = 1

        def replace(m):
            nonlocal status
            table = os.path.join(ROOT, "docs", "tables", m.group(2) + ".md")
            if not os.path.exists(table):
                print("%s: no table %s" % (os.path.relpath(path, ROOT), os.path.relpath(table, ROOT)))
                status = 1
                return m.group(0)
            body = open(table).read().rstrip("\n") + "\n"
            return m.group(1) + body + m.group(4)

        new = BLOCK.sub(replace, text)
        if new != text:
            names = [n for _, n, _, _ in BLOCK.findall(text)]
            if check:
                print("%s: differs from docs/tables (%s)" % (os.path.relpath(path, ROOT), ", ".join(names)))
                status = 1
            else:
                with open(path, "w") as f:
                    f.write(new)
                print("pasted into %s: %s" % (os.path.relpath(path, ROOT), ", ".join(names)))
    sys.exit(status)


if __name__ == "__main__":
    main()
