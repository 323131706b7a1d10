#!/usr/bin/env python3
"""Splits docs/figures/pictures/pictures.md (written by make.sh) into the two blocks docs/experiments.md
includes: docs/tables/pictures-gallery.md (the test scenes, without its heading: the section has one)
and docs/tables/pictures-curves.md (the error along a curve, the discontinuity mesh, the extended
ray), with the pictures' paths made relative to docs/."""
import os, re

HERE = os.path.dirname(os.path.abspath(__file__))
TABLES = os.path.join(HERE, "..", "..", "tables")
text = open(os.path.join(HERE, "pictures.md")).read()
text = re.sub(r"\]\(([a-z_]+\.png)\)", r"](figures/pictures/\1)", text)
sections = re.split(r"(?m)^(?=### )", text.strip())
sections = [s for s in sections if s.strip()]
gallery = sections[0].split("\n", 1)[1].strip()  # without "### The test scenes"
os.makedirs(TABLES, exist_ok=True)
with open(os.path.join(TABLES, "pictures-gallery.md"), "w") as f:
    f.write(gallery + "\n")
with open(os.path.join(TABLES, "pictures-curves.md"), "w") as f:
    f.write("\n\n".join(s.strip() for s in sections[1:]) + "\n")
