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
read with zlib).
"""
import argparse
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import zlib

LESSONS = ["mirror_room", "prism", "parabolic_mirror", "lens"]


def brightness(path):
    """The brightness (mean of r, g, b) of every pixel of an 8-bit RGB(A) PNG, row by row."""
    data = open(path, "rb").read()
    at, idat, header = 8, b"", None
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        at += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in (2, 6) or interlace != 0:
        sys.exit(f"{path}: expected an 8-bit RGB or RGBA PNG without interlacing")
    channels = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * channels
    previous = bytearray(stride)
    values = []
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            left = line[i - channels] if i >= channels else 0
            up = previous[i]
            corner = previous[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + left) & 255
            elif kind == 2:
                line[i] = (line[i] + up) & 255
            elif kind == 3:
                line[i] = (line[i] + (left + up) // 2) & 255
            elif kind == 4:
                p = left + up - corner
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
                line[i] = (line[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else corner)) & 255
        values.extend((line[x * channels] + line[x * channels + 1] + line[x * channels + 2]) / 3.0
                      for x in range(width))
        previous = line
    return values


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
