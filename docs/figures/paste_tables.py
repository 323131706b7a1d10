#!/usr/bin/env python3
"""Copies each generated table (docs/tables/NAME.md, written by docs/reproduce.sh) into README.md
and docs/*.md between the markers

    <!-- table NAME -->
    ...
    <!-- /table NAME -->

so that the documents show the numbers of the last run and no number is typed by hand. Prints what
it replaced; exits 1 when a marker names a table that does not exist or is not closed.

    python3 docs/figures/paste_tables.py [--check]

--check changes nothing: it prints, per document, the tables it compared and whether each block is
the table's text (naming the first line of a block that differs), then how many tables and numbers
it compared, and exits 1 when a block differs. docs/reproduce.sh --quick and CI run it, so that a
number edited in a document alone is caught."""
import glob, os, re, sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BLOCK = re.compile(r"(<!-- table ([A-Za-z0-9_-]+) -->\n)(.*?)(<!-- /table \2 -->)", re.S)
NUMBER = re.compile(r"\d+(\.\d+)?([eE][-+]?\d+)?")


def first_difference(pasted, table):
    """The first line where a pasted block and its table differ, said in one line."""
    a, b = pasted.split("\n"), table.split("\n")
    for i, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return "line %d of the block: %r against the table's %r" % (i + 1, x, y)
    return "the block has %d lines, the table %d" % (len(a), len(b))


def main():
    check = "--check" in sys.argv[1:]
    status = 0
    compared, numbers = 0, 0
    for path in [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md"))):
        text = open(path).read()
        opened = re.findall(r"<!-- table ([A-Za-z0-9_-]+) -->", text)
        closed = re.findall(r"<!-- /table ([A-Za-z0-9_-]+) -->", text)
        if sorted(opened) != sorted(closed):
            print("%s: a table marker is not closed (%s)" % (os.path.relpath(path, ROOT), sorted(set(opened) ^ set(closed))))
            status = 1

        same, differ = [], []

        def replace(m):
            nonlocal status, compared, numbers
            table = os.path.join(ROOT, "docs", "tables", m.group(2) + ".md")
            if not os.path.exists(table):
                print("%s: no table %s" % (os.path.relpath(path, ROOT), os.path.relpath(table, ROOT)))
                status = 1
                return m.group(0)
            body = open(table).read().rstrip("\n") + "\n"
            compared += 1
            numbers += len(NUMBER.findall(body))
            if m.group(3) == body:
                same.append(m.group(2))
            else:
                differ.append((m.group(2), first_difference(m.group(3), body)))
            return m.group(1) + body + m.group(4)

        new = BLOCK.sub(replace, text)
        if check and same:
            print("%s: %s: the same text as docs/tables" % (os.path.relpath(path, ROOT), ", ".join(same)))
        for name, where in differ if check else []:
            print("%s: %s DIFFERS from docs/tables/%s.md: %s" % (os.path.relpath(path, ROOT), name, name, where))
        if new != text:
            names = [n for _, n, _, _ in BLOCK.findall(text)]
            if check:
                status = 1
            else:
                with open(path, "w") as f:
                    f.write(new)
                print("pasted into %s: %s" % (os.path.relpath(path, ROOT), ", ".join(names)))
    if check:
        print("%d pasted tables (%d numbers) compared with docs/tables: %s" % (
            compared, numbers, "every one the same text" if status == 0 else "SOME DIFFER (above)"))
    sys.exit(status)


if __name__ == "__main__":
    main()
