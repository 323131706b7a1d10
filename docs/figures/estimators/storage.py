#!/usr/bin/env python3
"""Estimator against storage mesh (docs/storage-mesh.md, "Storage that follows the photons"): cubic storage
with the lumped, Galerkin and local estimators, each on 16 fixed elements per curve and on storage
that follows the photons (auto), at 1e5, 1e6 and 1e7 photons, on the penumbra and the curved room;
median relative L2 error of B - E over 3 seeds against `flatland reference` (N = 1600, checked to be
10x more accurate than the smallest error judged). Every other setting is pinned: reconstructed
origins, direct-light events, pseudo-random numbers (so that the estimator's bias is not hidden
behind Sobol' points' smaller noise, nor helped by them), point rays, 2 threads.

    docs/figures/estimators/storage.py        prints the tables (Markdown)
Environment: FLATLAND (default build/flatland)."""
import csv, os, re, statistics, subprocess, sys, tempfile

FLATLAND = os.environ.get("FLATLAND", "build/flatland")
SCENES = [("penumbra", "scenes2d/penumbra.json"), ("curved room", "scenes2d/curved_room.json")]
BUDGETS = ["1e5", "1e6", "1e7"]
COMMON = "basis=cubic+sampling=reconstructed+discontinuities=auto+sampler=random+ray-width=0+transport=shooting+gather=none"
ROWS = [(e, m) for e in ["lumped", "galerkin", "local"] for m in ["16", "auto"]]


def main():
    checks = []
    for name, scene in SCENES:
        work = tempfile.mkdtemp(prefix="flatland-estimators-")
        ref = os.path.join(work, "reference.json")
        subprocess.run([FLATLAND, "reference", scene, "--elements", "1600", "--threads", "2", "--quiet", "--out", ref],
                       check=True)
        methods = ["%s+estimator=%s+elements=%s" % (COMMON, e, m) for e, m in ROWS]
        done = subprocess.run([FLATLAND, "converge", scene, "--reference", ref, "--methods", ",".join(methods),
                               "--budgets", ",".join(BUDGETS), "--seeds", "3", "--threads", "2", "--out", work],
                              check=True, capture_output=True, text=True)
        floor = float(re.search(r"reference error \(estimated\) ([0-9.eE+-]+)", done.stdout).group(1))
        with open(os.path.join(work, "convergence.csv")) as f:
            rows = list(csv.DictReader(f))
        # converge writes each method's budgets in order, seeds 1..3 within each
        med = {}
        for i, m in enumerate(methods):
            runs = [r for r in rows if r["method"] == m]
            med[m] = [statistics.median(float(r["rel_l2"]) for r in runs[3 * b:3 * b + 3]) for b in range(len(BUDGETS))]
        smallest = min(min(v) for v in med.values())
        checks.append("%s: reference error %.2g against %.2g, %s" % (
            name, floor, smallest, "good enough" if 10 * floor <= smallest else "NOT 10x below"))
        print("%s (`%s`):" % (name.capitalize(), scene))
        print()
        print("| estimator, storage | %s |" % " | ".join(b + " photons" for b in BUDGETS))
        print("|---|%s" % ("---|" * len(BUDGETS)))
        for (e, m), method in zip(ROWS, methods):
            print("| %s, %s | %s |" % (e, "16 fixed" if m == "16" else "auto", " | ".join("%.2e" % v for v in med[method])))
        print()
    print("References: " + "; ".join(checks) + ".")
    if any("NOT" in c for c in checks):
        sys.exit("a reference is not 10x more accurate than the errors it judges")


if __name__ == "__main__":
    main()
