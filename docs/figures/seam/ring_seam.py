#!/usr/bin/env python3
"""The seam of a closed curve, measured: a ring of eight cubic arcs (radius 1, rho = 0.5) with a
smooth emittance profile E(phi) = 1 + 0.8 sin(phi), steepest at the closing point (phi = 0). The
exact answer is diagonal in Fourier series (docs/storage-mesh.md, "Closed curves"): with the kernel
k(psi) = |sin(psi / 2)| / 4 per unit angle, B_n = E_n / (1 - rho lambda_n), lambda_0 = 1,
lambda_n = -1 / (4 n^2 - 1). E_n are taken from the profile as the scene file states it (a cubic
Bernstein polynomial of the control points' factors along each arc), at the arcs' true angles.

Solves the ring written as format version 2 (periodic: the closing point is a joint) and as
version 1 (the closing point a seam) with several seeds, and prints the RMS error of B within
0.4 rad of the closing point and elsewhere, as a Markdown table with a row per basis. Every other
setting is pinned (16 elements per curve, lumped deposits: the seam's O(h) end bias is the lumped
estimate's; pseudo-random numbers, reconstructed origins, point rays), so a change of the program's
defaults does not change what this measures.

Usage: [FLATLAND=PATH] docs/figures/seam/ring_seam.py [BUILD_DIR] [PHOTONS] [SEEDS] [BASES, comma-separated]
The program is FLATLAND (as docs/reproduce.sh sets it), else BUILD_DIR/flatland (BUILD_DIR defaults
to build)."""
import json
import math
import os
import subprocess
import sys
import tempfile

build = sys.argv[1] if len(sys.argv) > 1 else "build"
flatland = os.environ.get("FLATLAND") or os.path.join(build, "flatland")
photons = sys.argv[2] if len(sys.argv) > 2 else "1e7"
seeds = int(sys.argv[3]) if len(sys.argv) > 3 else 3
bases = (sys.argv[4] if len(sys.argv) > 4 else "cubic,linear").split(",")
PIN = ["--elements", "16", "--estimator", "lumped", "--sampler", "random", "--sampling", "reconstructed",
       "--discontinuities", "auto", "--ray-width", "0", "--transport", "shooting", "--gather", "none", "--control-variate", "none", "--threads", "2"]
RHO = 0.5
SAMPLES = 400


def profile(phi):
    return 1.0 + 0.8 * math.sin(phi)


def ring_scene(version):
    h = 4.0 / 3.0 * math.tan(math.pi / 16.0)
    points, factors = [], []
    for i in range(8):
        a, b = i * math.pi / 4, (i + 1) * math.pi / 4
        d = (b - a) / 3.0  # Hermite-like factors: the Bernstein form matches value and slope
        if i == 0:
            points.append([1.0, 0.0])
            factors.append(profile(a))
        points.append([math.cos(a) - h * math.sin(a), math.sin(a) + h * math.cos(a)])
        points.append([math.cos(b) + h * math.sin(b), math.sin(b) - h * math.cos(b)])
        points.append([1.0, 0.0] if i == 7 else [math.cos(b), math.sin(b)])
        factors += [profile(a) + d * 0.8 * math.cos(a), profile(b) - d * 0.8 * math.cos(b), profile(b)]
    factors[-1] = factors[0]
    return {"flatland": version, "name": "ring_seam",
            "materials": {"wall": {"reflectivity": RHO, "emittance": 1.0}},
            "curves": [{"id": "ring", "material": "wall", "bezier": points,
                        "emittance_profile": factors}]}


def bezier(p, t):
    s = 1 - t
    return [s**3 * p[0][k] + 3 * s * s * t * p[1][k] + 3 * s * t * t * p[2][k] + t**3 * p[3][k]
            for k in range(2)]


def emittance_at(scene, u):
    c = scene["curves"][0]
    j = min(int(u), 7)
    t = u - j
    f = c["emittance_profile"][3 * j:3 * j + 4]
    s = 1 - t
    return s**3 * f[0] + 3 * s * s * t * f[1] + 3 * s * t * t * f[2] + t**3 * f[3]


def exact(scene, terms=64, steps=8192):
    """B(phi) from the Fourier solution; E_n by the trapezoid rule in angle over a fine sampling."""
    c = scene["curves"][0]["bezier"]
    angles, values = [], []
    for i in range(steps):
        u = 8.0 * i / steps
        j = min(int(u), 7)
        x, y = bezier(c[3 * j:3 * j + 4], u - j)
        angles.append(math.atan2(y, x) % (2 * math.pi))
        values.append(emittance_at(scene, u))
    # Resample E on a uniform angle grid by linear interpolation (angles increase along the ring).
    order = sorted(range(steps), key=lambda i: angles[i])
    angles = [angles[i] for i in order]
    values = [values[i] for i in order]
    grid = [2 * math.pi * i / steps for i in range(steps)]
    e = []
    k = 0
    for g in grid:
        while k + 1 < steps and angles[k + 1] <= g:
            k += 1
        a0, a1 = angles[k], angles[(k + 1) % steps] + (2 * math.pi if k + 1 == steps else 0)
        w = (g - a0) / (a1 - a0) if a1 > a0 else 0.0
        e.append(values[k] * (1 - w) + values[(k + 1) % steps] * w)
    coeffs = []
    for n in range(terms):
        cn = sum(v * math.cos(n * g) for v, g in zip(e, grid)) / steps
        sn = sum(v * math.sin(n * g) for v, g in zip(e, grid)) / steps
        lam = 1.0 if n == 0 else -1.0 / (4 * n * n - 1)
        coeffs.append((cn, sn, 1.0 / (1.0 - RHO * lam)))

    def b(phi):
        total = 0.0
        for n, (cn, sn, gain) in enumerate(coeffs):
            weight = 1.0 if n == 0 else 2.0
            total += weight * gain * (cn * math.cos(n * phi) + sn * math.sin(n * phi))
        return total
    return b


def main():
    print("| storage | periodic (format 2): near / elsewhere | seam (format 1): near / elsewhere |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for basis in bases:
            cells = []
            for version in (2, 1):
                scene = ring_scene(version)
                path = os.path.join(tmp, f"ring_v{version}.json")
                with open(path, "w") as f:
                    json.dump(scene, f)
                b = exact(scene)
                near, away = [], []
                for seed in range(1, seeds + 1):
                    out = os.path.join(tmp, "out.json")
                    subprocess.run([flatland, "solve", path, "--photons", photons,
                                    "--seed", str(seed), "--basis", basis, "--tolerance", "1e-6",
                                    "--samples", str(SAMPLES), "--out", out] + PIN,
                                   check=True, stdout=subprocess.DEVNULL)
                    with open(out) as f:
                        samples = json.load(f)["curves"][0]["samples"]
                    n2 = a2 = 0.0
                    nn = na = 0
                    for sample in samples:
                        phi = math.atan2(sample["y"], sample["x"])
                        err = (sample["B"] - b(phi)) ** 2
                        if abs(phi) < 0.4:
                            n2 += err
                            nn += 1
                        else:
                            a2 += err
                            na += 1
                    near.append(math.sqrt(n2 / nn))
                    away.append(math.sqrt(a2 / na))
                cells.append("%.2e / %.2e (%.2f)" % (sum(near) / len(near), sum(away) / len(away), sum(near) / sum(away)))
            print("| %s | %s | %s |" % (basis, cells[0], cells[1]))


if __name__ == "__main__":
    main()
