#!/usr/bin/env python3
"""How much the light's structure stands out of its haze on the stage, paths against the field
(docs/viewer.md, "The light as a field").

  python3 bench/light_contrast.py [--binary build/flatland] [SCENE ...]

For each scene (default: the four optics lessons) the viewer solves the default 1e6 photons to the
end, one round a frame, under a virtual X server (xvfb-run), and writes the stage as a PNG with
`--light paths` and with `--light field`. Printed per picture: the lit pixels (those brighter than
the background by more than 8 of 255), the median and 95th percentile of their brightness (the
mean of r, g and b), and p95 / p50: near 1 when everything lit is equally bright (a washed-out
haze), larger when beams, caustics and reflections stand out. Standard library only (the PNG is
read by tests/web/png_pixels.py).
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "web"))
from png_pixels import png_pixels  # noqa: E402 (after the path it needs)

LESSONS = ["mirror_room", "prism", "parabolic_mirror", "lens"]


def brightness(path):
    """The brightness (mean of r, g, b) of every pixel of an 8-bit RGB(A) PNG, row by row."""
    _, _, rows = png_pixels(path)
    return [sum(pixel) / 3.0 for row in rows for pixel in row]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--binary", default="build/flatland")
    parser.add_argument("scenes", nargs="*", default=LESSONS)
    args = parser.parse_args()
    if not os.access(args.binary, os.X_OK) or os.path.isdir(args.binary):
        sys.exit(f"{args.binary}: not an executable; build it first (cmake --build build --target flatland)")
    with tempfile.TemporaryDirectory() as directory:
        for scene in args.scenes:
            for light in ("paths", "field"):
                out = os.path.join(directory, f"{scene}_{light}.png")
                command = ["xvfb-run", "-a", "-s", "-screen 0 1400x900x24", args.binary, "view",
                           f"scenes2d/{scene}.json", "--frames", "40", "--step", "rounds=1", "--light", light,
                           "--screenshot", out]
                run = subprocess.run(command, capture_output=True, text=True)
                if run.returncode != 0:
                    sys.exit(f"{' '.join(command)}: {run.stderr.strip()}")
                values = brightness(out)
                background = statistics.median(values[:50])
                lit = sorted(v for v in values if v > background + 8)
                p50 = lit[len(lit) // 2]
                p95 = lit[int(0.95 * (len(lit) - 1))]
                print(f"{scene:18s} {light:5s}  lit pixels {len(lit):7d}  p50 {p50:5.1f}  p95 {p95:5.1f}  "
                      f"p95/p50 {p95 / p50:.2f}", flush=True)


if __name__ == "__main__":
    main()
