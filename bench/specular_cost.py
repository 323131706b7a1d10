#!/usr/bin/env python3
"""The cost of specular chains (docs/performance.md, "Mirrors, glass and detectors").

Two measurements, each interleaved (A B A B ...) so that the machine's drift falls on both sides:

1. Scenes without mirrors or glass, this build against an older one (--baseline): a scene without
   specular curves must run the loops it ran before. Median solve seconds (the summary's "solved"
   line: the solve alone) of --runs runs each, and their ratio.
2. Every teaching scene with mirrors, glass or detectors, and diffuse scenes for contrast: photons
   and rays per second and rays per photon (a chain's every event is a ray).

  bench/specular_cost.py [--flatland build/flatland] [--baseline OLD/flatland] [--runs 5] [--photons 2e6]
"""
import argparse
import os
import re
import statistics
import subprocess

DIFFUSE = ["scenes2d/penumbra.json", "scenes2d/curved_room.json", "scenes2d/default.json"]
SPECULAR = ["scenes2d/lens.json", "scenes2d/parabolic_mirror.json", "scenes2d/prism.json",
            "scenes2d/light_guide.json", "scenes2d/mirror_room.json"]
SOLVED = re.compile(r"solved\s+\S+ photons \((\S+) rays\) in \d+ rounds, ([0-9.]+) s")


def count(text):
    """'1.07M' -> 1.07e6."""
    scale = {"k": 1e3, "M": 1e6, "G": 1e9}
    return float(text[:-1]) * scale[text[-1]] if text[-1] in scale else float(text)


def solve(flatland, scene, photons, seed):
    out = subprocess.run([flatland, "solve", scene, "--photons", str(photons), "--seed", str(seed), "--threads", "1"],
                         capture_output=True, text=True, check=True).stdout
    photons_line = re.search(r"solved\s+(\S+) photons", out).group(1)
    rays, seconds = SOLVED.search(out).groups()
    return count(photons_line), count(rays), float(seconds)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--flatland", default=os.environ.get("FLATLAND", "build/flatland"))
    parser.add_argument("--baseline", help="an older build's flatland, for the diffuse scenes' ratio")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--photons", default="2e6")
    args = parser.parse_args()
    if args.baseline:
        print("| scene | baseline s (median) | this build s (median) | ratio |")
        print("|---|---|---|---|")
        for scene in DIFFUSE:
            old, new = [], []
            for run in range(args.runs):
                old.append(solve(args.baseline, scene, args.photons, run + 1)[2])
                new.append(solve(args.flatland, scene, args.photons, run + 1)[2])
            a, b = statistics.median(old), statistics.median(new)
            print(f"| {os.path.basename(scene)} | {a:.3f} | {b:.3f} | {b / a:.3f} |", flush=True)
        print()
    print("| scene | photons/s (median) | rays/s (median) | rays per photon |")
    print("|---|---|---|---|")
    for scene in DIFFUSE + SPECULAR:
        rates, ray_rates, per_photon = [], [], []
        for run in range(args.runs):
            photons, rays, seconds = solve(args.flatland, scene, args.photons, run + 1)
            rates.append(photons / seconds)
            ray_rates.append(rays / seconds)
            per_photon.append(rays / photons)
        print(f"| {os.path.basename(scene)} | {statistics.median(rates) / 1e6:.2f} M | "
              f"{statistics.median(ray_rates) / 1e6:.2f} M | {statistics.median(per_photon):.2f} |", flush=True)


if __name__ == "__main__":
    main()
