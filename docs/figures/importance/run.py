#!/usr/bin/env python3
"""Importance toward a region of interest, measured: the region's error, the rest's, and the time.

Every scene below is solved with and without `--importance REGION` at each budget and seed, and
judged against a fine reference of the scene: the relative L2 error of B - E on the region's curve
(`flatland compare --json`, its curve row) and over the whole scene, and the solve's wall time
(the adjoint solve and the count of every round's sources included). Every solver setting is
spelled out in SETTINGS below, so a change of the program's defaults does not change what this
measures.

    docs/figures/importance/run.py [--tables DIR] [--out DIR]

Writes TABLES/importance.md: per scene, region, gather and budget, the medians over the seeds of the
region's error without and with importance, the ratio of the scene's error, of the time, and the
region's efficiency 1 / (error^2 x time) with importance over without; then findings computed
from the rows. Environment: FLATLAND (default build/flatland), THREADS (default 2)."""
import argparse, json, os, statistics, subprocess, sys, time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
FLATLAND = os.environ.get("FLATLAND", "build/flatland")
THREADS = os.environ.get("THREADS", "2")
SEEDS = 8
BUDGETS = ["1e5", "1e6"]
REFERENCE_RESOLUTION = 1200  # elements no longer than the scene's size / N
# name -> (scene file, region, why it is a region of interest)
SCENES = {
    "row_of_rooms": ("scenes2d/row_of_rooms.json", "desk", "a desk in the first of four rooms"),
    "office": ("scenes2d/interreflection/office.json", "desk", "a desk in a closed office"),
    "window_room": ("scenes2d/interreflection/window_room.json", "table", "a table in a room lit through a window"),
    "default": ("scenes2d/default.json", "sofa", "the sofa of the default scene"),
    "penumbra": ("scenes2d/penumbra.json", "receiver", "the receiver of the penumbra scene (one emitter)"),
}
SETTINGS = ["--basis", "cubic", "--estimator", "galerkin", "--elements", "auto", "--sampling", "reconstructed",
            "--discontinuities", "auto", "--sampler", "sobol", "--ray-width", "0", "--transport", "shooting",
            "--replicates", "8", "--tolerance", "1e-3", "--samples", "100"]
# The storage's own B, and B from a final gather of it (the default where the scene allows one).
GATHERS = ["none", "samples"]


def run(args):
    return subprocess.run(args, cwd=ROOT, check=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def solve(path, photons, seed, gather, region, out):
    """One solve into out; its wall time in seconds."""
    start = time.perf_counter()
    run([FLATLAND, "solve", path, "--photons", photons, "--seed", str(seed), "--threads", THREADS, "--quiet",
         "--gather", gather, "--out", out] + SETTINGS + (["--importance", region] if region else []))
    return time.perf_counter() - start


def errors(result, reference, region):
    errs = json.loads(run([FLATLAND, "compare", result, reference, "--json"]).stdout)
    curve = next(c for c in errs["curves"] if c["id"] == region)
    return curve["l2"], errs["scene"]["l2"]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--tables", default=os.path.join(ROOT, "docs", "tables"))
    parser.add_argument("--out", default=os.path.join(ROOT, "build", "reproduce", "importance"))
    a = parser.parse_args()
    os.makedirs(a.out, exist_ok=True)
    lines = ["| scene | region | gather | photons | region's error without | with | scene's error, ratio "
             "| time, ratio | region's efficiency |",
             "|---|---|---|---|---|---|---|---|---|"]
    gains = []  # (scene, budget, gather, region's efficiency ratio, scene's error ratio, time ratio)
    for scene, (path, region, _) in SCENES.items():
        reference = os.path.join(a.out, scene + "-reference.json")
        run([FLATLAND, "reference", path, "--elements", str(REFERENCE_RESOLUTION), "--threads", THREADS,
             "--no-error-estimate", "--quiet", "--out", reference])
        for gather in GATHERS:
            for budget in BUDGETS:
                by = {}
                for seed in range(1, SEEDS + 1):
                    # Interleaved, so that the machine's drift falls on both alike.
                    for name, favoured in (("without", ""), ("with", region)):
                        out = os.path.join(a.out, "%s-%s-%s-%d-%s.json" % (scene, gather, budget, seed, name))
                        seconds = solve(path, budget, seed, gather, favoured, out)
                        by.setdefault(name, []).append(errors(out, reference, region) + (seconds,))
                med = {name: [statistics.median(r[i] for r in runs) for i in range(3)] for name, runs in by.items()}
                (r0, s0, t0), (r1, s1, t1) = med["without"], med["with"]
                efficiency = (r0 ** 2 * t0) / (r1 ** 2 * t1)
                gains.append((scene, budget, gather, efficiency, s1 / s0, t1 / t0))
                lines.append("| %s | %s | %s | %s | %.3g %% | %.3g %% | %.2fx | %.2fx | %.2fx |" % (
                    scene.replace("_", " "), region, gather, budget, 100 * r0, 100 * r1, s1 / s0, t1 / t0,
                    efficiency))
                print("%s %s %s: region %.4g -> %.4g, scene x%.2f, time x%.2f, efficiency x%.2f" % (
                    scene, gather, budget, r0, r1, s1 / s0, t1 / t0, efficiency), flush=True)
    head = ("%d seeds, %s threads; medians; relative L2 error of B - E against `flatland reference --elements %d`; "
            "the scene's error and the time with importance over without; the region's efficiency is "
            "1 / (error^2 x time) with importance over without (above 1: importance pays). Settings: `%s`.\n\n"
            % (SEEDS, THREADS, REFERENCE_RESOLUTION, " ".join(SETTINGS)))
    at_large = [g for g in gains if g[1] == BUDGETS[-1]]
    findings = []
    for gather in GATHERS:
        runs = [g for g in at_large if g[2] == gather]
        best = max(runs, key=lambda g: g[3])
        worst = min(runs, key=lambda g: g[3])
        findings.append("- Gather %s, %s photons: the region's efficiency with importance is %.2fx (%s) to %.2fx (%s); "
                        "the scene's error is %.2f-%.2fx what it is without." % (
                            gather, BUDGETS[-1], worst[3], worst[0].replace("_", " "), best[3],
                            best[0].replace("_", " "), min(g[4] for g in runs), max(g[4] for g in runs)))
    findings.append("- The adjoint solve and the count of the sources cost %.2f-%.2fx the time at %s photons and "
                    "%.2f-%.2fx at %s." % (
                        min(g[5] for g in gains if g[1] == BUDGETS[0]), max(g[5] for g in gains if g[1] == BUDGETS[0]),
                        BUDGETS[0], min(g[5] for g in at_large), max(g[5] for g in at_large), BUDGETS[-1]))
    os.makedirs(a.tables, exist_ok=True)
    with open(os.path.join(a.tables, "importance.md"), "w") as f:
        f.write(head + "\n".join(lines) + "\n\n" + "\n".join(findings) + "\n")


if __name__ == "__main__":
    sys.exit(main())
