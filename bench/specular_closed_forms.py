#!/usr/bin/env python3
"""Mirrors and glass against closed forms, through the command line
(docs/experiments-error-and-optics.md, "Mirrors, glass and dispersion"). Four measurements, each
printed as a Markdown table (also DIR/*.md):

1. mirror: a floor lit by a lamp and a flat mirror standing on the floor's line, against the image
   method, rho (H_lamp + reflectance H_image) with H = (sin a2 - sin a1) / 2 per source; beside it
   the same floor lit by the lamp and an explicit second lamp at the image (the mirror's
   reflectance 1 and the image lamp give the same closed form): relative L1 and Linf of B - E over
   the floor's samples, the default method, median of the seeds with its interquartile range.
2. slab: the power through a glass slab (index 1.5) onto a detector under it, a narrow beam at
   angles 0 to 85 degrees, against (1 - R) / (1 + R) with R Fresnel's unpolarised reflectance.
3. critical: a beam inside glass meeting its top face at angles around the critical angle
   asin(1 / 1.5) = 41.81 degrees; the power out through the face (a detector over the first exit)
   against 1 - R, which falls to 0 there.
4. prism: line spectra at 450, 550 and 650 nm through a dense flint prism (Cauchy index
   1.62 + 0.0145 / lambda^2); two detectors behind it give each beam's direction from the centroids
   of their bins, against the textbook's deviation theta1 + theta2' - A.

  bench/specular_closed_forms.py --out DIR [--flatland build/flatland] [--photons 1e6] [--seeds 5]
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "figures"))
import spread  # noqa: E402 (after the path it needs)


def fresnel(n1, n2, cos_in):
    eta = n1 / n2
    sin2 = eta * eta * (1.0 - cos_in * cos_in)
    if sin2 >= 1.0:
        return 1.0
    cos_out = math.sqrt(1.0 - sin2)
    rs = (n1 * cos_in - n2 * cos_out) / (n1 * cos_in + n2 * cos_out)
    rp = (n1 * cos_out - n2 * cos_in) / (n1 * cos_out + n2 * cos_in)
    return 0.5 * (rs * rs + rp * rp)


def beam_average(f, degrees, half_angle):
    """Mean of f(theta) over a beam: sin(theta - tilt) uniform within the half-angle."""
    n = 2000
    total = 0.0
    s = math.sin(math.radians(half_angle))
    for i in range(n):
        total += f(math.radians(degrees) + math.asin((2.0 * (i + 0.5) / n - 1.0) * s))
    return total / n


class Runner:
    def __init__(self, flatland, directory):
        self.flatland = flatland
        self.directory = directory

    def solve(self, scene, photons, seed, *extra):
        path = os.path.join(self.directory, "scene.json")
        with open(path, "w") as f:
            json.dump(scene, f)
        out = os.path.join(self.directory, "result.json")
        csv_path = os.path.join(self.directory, "detectors.csv")
        # Every setting pinned to the defaults of the program measured (cubic, Galerkin, storage that
        # follows the photons, reconstructed origins, direct-light events, Sobol' points, point rays),
        # so a change of defaults does not change what this measures.
        args = [self.flatland, "solve", path, "--photons", str(photons), "--seed", str(seed), "--quiet", "--out", out,
                "--basis", "cubic", "--estimator", "galerkin", "--elements", "auto", "--sampling", "reconstructed",
                "--discontinuities", "auto", "--sampler", "sobol", "--ray-width", "0", "--transport", "shooting", "--gather", "none", "--control-variate", "none",
                "--threads", "2"]
        if any(m.get("type") == "detector" for m in scene["materials"].values()):
            args += ["--detectors", csv_path]
        subprocess.run(args + list(extra), check=True)
        with open(out) as f:
            result = json.load(f)
        rows = []
        if os.path.exists(csv_path):
            with open(csv_path) as f:
                rows = list(csv.DictReader(f))
            os.remove(csv_path)
        return result, rows


def front_total(rows, detector):
    return sum(float(r["front"]) for r in rows if r["detector"] == detector)


# ---- 1. the image method

def mirror_scene(image_lamp):
    lamp = {"id": "lamp", "material": "lamp", "line": [[0.8, 1.0], [0.3, 1.0]]}
    floor = {"id": "floor", "material": "floor", "line": [[0.05, 0.0], [2.0, 0.0]]}
    if image_lamp:
        other = {"id": "image", "material": "lamp", "line": [[-0.3, 1.0], [-0.8, 1.0]]}
    else:
        other = {"id": "mirror", "material": "mirror", "line": [[0.0, 1.5], [0.0, 0.0]]}
    return {"flatland": 2, "materials": {"lamp": {"emittance": 1}, "floor": {"reflectivity": 0.5},
                                         "mirror": {"type": "mirror", "reflectance": 1.0}},
            "curves": [lamp, floor, other]}


def image_irradiance(x):
    def sine(px):
        return (px - x) / math.hypot(px - x, 1.0)
    return 0.5 * ((sine(0.8) - sine(0.3)) + (sine(-0.3) - sine(-0.8)))


def mirror_table(runner, photons, seeds):
    lines = ["Relative L1 and Linf of B - E over the floor, each the %s:" % spread.caption(seeds), "",
             "| floor lit by | photons | relative L1 | relative Linf |", "|---|---|---|---|"]
    for image_lamp in (False, True):
        for n in photons:
            l1s, linfs = [], []
            for seed in range(1, seeds + 1):
                result, _ = runner.solve(mirror_scene(image_lamp), n, seed)
                floor = next(c for c in result["curves"] if c["id"] == "floor")
                errors = [s["B"] - 0.5 * image_irradiance(s["x"]) for s in floor["samples"]]
                exact = [0.5 * image_irradiance(s["x"]) for s in floor["samples"]]
                l1s.append(sum(abs(e) for e in errors) / sum(exact))
                linfs.append(max(abs(e) for e in errors) / max(exact))
            what = "lamp and a second lamp at its image" if image_lamp else "lamp and a flat mirror (reflectance 1)"
            e2 = lambda v: "%.2e" % v  # noqa: E731
            lines.append(f"| {what} | {n:.0e} | {spread.cell(l1s, e2)} | {spread.cell(linfs, e2)} |")
    return lines


# ---- 2. the slab

def slab_scene(degrees, half_angle):
    a = math.radians(degrees)
    cx, cy = -math.tan(a), 1.0
    dx, dy = 0.1 * math.cos(a), 0.1 * math.sin(a)
    return {"flatland": 2,
            "materials": {"lamp": {"emittance": 1, "emission": {"beam": half_angle}},
                          "glass": {"type": "dielectric", "ior": 1.5}, "detector": {"type": "detector", "bins": 1}},
            "curves": [{"id": "lamp", "material": "lamp", "line": [[cx + dx, cy + dy], [cx - dx, cy - dy]]},
                       {"id": "slab", "material": "glass",
                        "line": [[-50, -0.1], [50, -0.1], [50, 0], [-50, 0], [-50, -0.1]]},
                       {"id": "under", "material": "detector", "line": [[-60, -0.5], [60, -0.5]]}]}


def slab_table(runner, photons):
    half = 0.5
    lines = ["| angle | through, measured | (1 - R) / (1 + R) | (1 - R)^2, one pass | measured - closed form | sigma |",
             "|---|---|---|---|---|---|"]
    for degrees in (0, 15, 30, 45, 60, 70, 75, 80, 85):
        result, rows = runner.solve(slab_scene(degrees, half), photons, 1)
        emitted = result["stats"]["emitted_power"]
        through = front_total(rows, "under") / emitted
        expected = beam_average(lambda t: (1 - fresnel(1, 1.5, math.cos(t))) / (1 + fresnel(1, 1.5, math.cos(t))),
                               degrees, half)
        once = beam_average(lambda t: (1 - fresnel(1, 1.5, math.cos(t))) ** 2, degrees, half)
        sigma = math.sqrt(expected * (1 - expected) / result["stats"]["photons"])
        lines.append(f"| {degrees} | {through:.5f} | {expected:.5f} | {once:.5f} | {through - expected:+.5f} | "
                     f"{sigma:.5f} |")
    return lines


# ---- 3. the critical angle

def critical_scene(degrees, half_angle):
    a = math.radians(degrees)
    dx, dy = 0.005 * math.cos(a), 0.005 * math.sin(a)
    # The lamp 0.01 under the top face of a deep, wide block, its front up turned by a to the left;
    # a detector just over the face around the first exit, which light coming back (after the
    # bottom, 50 below) cannot reach.
    exit_x = -0.01 * math.tan(a)
    return {"flatland": 2,
            "materials": {"lamp": {"emittance": 1, "emission": {"beam": half_angle}},
                          "glass": {"type": "dielectric", "ior": 1.5}, "detector": {"type": "detector", "bins": 1}},
            "curves": [{"id": "lamp", "material": "lamp", "line": [[-dx, -0.01 - dy], [dx, -0.01 + dy]]},
                       {"id": "block", "material": "glass",
                        "line": [[-50, -50], [50, -50], [50, 0], [-50, 0], [-50, -50]]},
                       {"id": "over", "material": "detector",
                        "line": [[exit_x + 1.0, 0.001], [exit_x - 1.0, 0.001]]}]}


def critical_table(runner, photons):
    half = 0.05
    critical = math.degrees(math.asin(1 / 1.5))
    lines = [f"| angle (critical {critical:.3f}) | out, measured | 1 - R | measured - closed form | sigma |",
             "|---|---|---|---|---|"]
    for degrees in (30, 38, 40, 41, 41.5, 41.7, 41.9, 42, 45):
        result, rows = runner.solve(critical_scene(degrees, half), photons, 1)
        out = front_total(rows, "over") / result["stats"]["emitted_power"]
        expected = beam_average(lambda t: 1 - fresnel(1.5, 1, math.cos(t)), degrees, half)
        sigma = math.sqrt(max(expected * (1 - expected), 1e-300) / result["stats"]["photons"])
        lines.append(f"| {degrees} | {out:.5f} | {expected:.5f} | {out - expected:+.5f} | {sigma:.5f} |")
    return lines


# ---- 4. the prism

def prism_scene(nanometres):
    theta1 = math.radians(50.0)
    angle = math.radians(-30.0) + theta1
    d = (math.cos(angle), math.sin(angle))
    target = (-0.5, math.sqrt(3) / 2)
    c = (target[0] - 1.5 * d[0], target[1] - 1.5 * d[1])
    along = (d[1], -d[0])
    lamp = [[c[0] - 0.005 * along[0], c[1] - 0.005 * along[1]], [c[0] + 0.005 * along[0], c[1] + 0.005 * along[1]]]
    return {"flatland": 2,
            "materials": {"lamp": {"emittance": 1, "emission": {"beam": 0.01}, "spectrum": {"line": nanometres}},
                          "glass": {"type": "dielectric", "ior": {"cauchy": [1.62, 0.0145]}},
                          "detector": {"type": "detector", "bins": 4096}},
            "curves": [{"id": "lamp", "material": "lamp", "line": lamp},
                       {"id": "prism", "material": "glass", "line": [[-1, 0], [1, 0], [0, math.sqrt(3)], [-1, 0]]},
                       {"id": "near", "material": "detector", "line": [[2.0, -3.0], [2.0, 2.0]]},
                       {"id": "far", "material": "detector", "line": [[3.0, -3.0], [3.0, 2.0]]}]}


def centroid(rows, detector):
    """Power-weighted mean y of a detector's bins near its brightest one (channels summed)."""
    bins = [(float(r["y"]), sum(float(r[k]) for k in ("front_r", "front_g", "front_b")))
            for r in rows if r["detector"] == detector]
    peak = max(bins, key=lambda b: b[1])[0]
    near = [(y, w) for y, w in bins if abs(y - peak) < 0.05]
    return sum(y * w for y, w in near) / sum(w for _, w in near)


def prism_table(runner, photons):
    lines = ["| wavelength | index | deviation, measured | theta1 + theta2' - A | difference |", "|---|---|---|---|---|"]
    theta1 = math.radians(50.0)
    incoming = math.radians(-30.0) + theta1
    for nm in (450, 550, 650):
        _, rows = runner.solve(prism_scene(nm), photons, 1)
        direction = math.atan2(centroid(rows, "far") - centroid(rows, "near"), 1.0)
        measured = math.degrees(incoming - direction)
        n = 1.62 + 0.0145 / (nm / 1000) ** 2
        t1p = math.asin(math.sin(theta1) / n)
        expected = math.degrees(theta1 + math.asin(n * math.sin(math.radians(60) - t1p)) - math.radians(60))
        lines.append(f"| {nm} nm | {n:.4f} | {measured:.3f} | {expected:.3f} | {measured - expected:+.3f} |")
    return lines


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--flatland", default=os.environ.get("FLATLAND", "build/flatland"))
    parser.add_argument("--photons", type=float, default=1e6)
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    photons = int(args.photons)
    with tempfile.TemporaryDirectory() as scratch:
        runner = Runner(args.flatland, scratch)
        for name, lines in (("mirror", mirror_table(runner, [photons // 10, photons], args.seeds)),
                            ("slab", slab_table(runner, photons)),
                            ("critical", critical_table(runner, photons)),
                            ("prism", prism_table(runner, photons))):
            text = "\n".join(lines) + "\n"
            with open(os.path.join(args.out, name + ".md"), "w") as f:
                f.write(text)
            print(text, flush=True)


if __name__ == "__main__":
    main()
