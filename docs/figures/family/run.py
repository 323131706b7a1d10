#!/usr/bin/env python3
"""The Monte Carlo radiosity family side by side, and the deterministic reference as a competitor.

Every method below is solved at every photon budget and seed on eight scenes by `flatland converge`
against a fine reference of each scene, and read as the median relative L2 error of B - E against
the median time (a method that gathers is timed with its gather: elements, sweeps and the estimate
through them). The deterministic reference is timed too: `flatland reference` at coarser
resolutions, each judged against the fine one, so a reader sees where Monte Carlo wins and where it
does not. Every solver setting is spelled out in the method strings.

    docs/figures/family/run.py [--tables DIR] [--out DIR]

Writes DIR/<scene>/convergence.csv (the runs), DIR/<scene>/reference-times.csv (the coarse
references) and the tables
  TABLES/family.md           per scene: each method's error at 1e6 photons, its time, its
                             efficiency 1 / (error^2 x time) over progressive shooting's at the same
                             budget, and its time to 1 % and 0.1 %; the reference's time to the same
  TABLES/family-findings.md  what the runs say, computed from them
Environment: FLATLAND (default build/flatland), THREADS (default 2), FAMILY_SCENES and
FAMILY_BUDGETS (comma lists, for trying the script on less)."""
import argparse, csv, json, math, os, statistics, subprocess, sys, time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import spread  # noqa: E402 (after the path it needs)

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
FLATLAND = os.environ.get("FLATLAND", "build/flatland")
THREADS = os.environ.get("THREADS", "2")
SEEDS = 3
BUDGETS = os.environ.get("FAMILY_BUDGETS", "1e4,1e5,1e6,4e6").split(",")
FIXED = 1e6
TARGETS = [1e-2, 1e-3]
ROUND_OFF = 1e-10  # relative errors below this are the reference's own answer to round-off
# The control variate carries direct light without photons: below this its error is its projection's
# quadrature, not noise, and an efficiency would say nothing.
VARIATE_EXACT = 1e-8

# name -> (scene file, class, resolution N of the fine reference: elements no longer than size / N,
# finer than the gather's N = 400, so that the gather's own discretisation error is measured too).
SCENES = {
    "penumbra": ("scenes2d/penumbra.json", "direct light", 800),
    "round_occluder": ("scenes2d/tests/reference_round_occluder.json", "direct light", 1600),
    "lit_ring": ("docs/figures/time_to_accuracy/lit_ring.json", "closed form", 1600),
    "ring_profile": ("scenes2d/tests/reference_ring_profile.json", "closed form", 800),
    "curved_room": ("scenes2d/curved_room.json", "room", 1600),
    "default": ("scenes2d/default.json", "room", 1200),
    "office": ("scenes2d/interreflection/office.json", "interreflection", 1200),
    "window_room": ("scenes2d/interreflection/window_room.json", "interreflection", 1200),
}
# The coarse references timed against the fine one.
REFERENCE_RESOLUTIONS = [25, 50, 100, 200, 400]

COMMON = ("elements=auto+sampler=sobol+discontinuities=auto+sampling=reconstructed+ray-width=0"
          "+replicate-layout=independent")
# Replicates as blocks of one round's net (docs/estimated-error.md), everything else as COMMON.
BLOCKS = COMMON.replace("replicate-layout=independent", "replicate-layout=blocks")
METHODS = [  # (label, method string)
    ("shooting, cubic", "basis=cubic+estimator=galerkin+transport=shooting+control-variate=none+gather=none+" + COMMON),
    ("shooting, cubic, gather", "basis=cubic+estimator=galerkin+transport=shooting+control-variate=none+gather=samples+" + COMMON),
    ("shooting, linear, gather", "basis=linear+estimator=galerkin+transport=shooting+control-variate=none+gather=samples+" + COMMON),
    ("shooting, constant, gather", "basis=constant+estimator=galerkin+transport=shooting+control-variate=none+gather=samples+" + COMMON),
    ("shooting, hermite, gather", "basis=hermite+estimator=local+transport=shooting+control-variate=none+gather=samples+" + COMMON),
    ("shooting, cubic, blocks", "basis=cubic+estimator=galerkin+transport=shooting+control-variate=none+gather=none+" + BLOCKS),
    ("shooting, cubic, blocks, gather", "basis=cubic+estimator=galerkin+transport=shooting+control-variate=none+gather=samples+" + BLOCKS),
    ("shooting, cubic, coarse variate",
     "basis=cubic+estimator=galerkin+transport=shooting+control-variate=coarse+gather=none+" + COMMON),
    ("shooting, cubic, coarse variate, gather",
     "basis=cubic+estimator=galerkin+transport=shooting+control-variate=coarse+gather=samples+" + COMMON),
    ("shooting, linear, coarse variate, gather",
     "basis=linear+estimator=galerkin+transport=shooting+control-variate=coarse+gather=samples+" + COMMON),
    ("jacobi, cubic", "basis=cubic+estimator=galerkin+transport=jacobi+control-variate=none+gather=none+" + COMMON),
    ("jacobi, cubic, gather", "basis=cubic+estimator=galerkin+transport=jacobi+control-variate=none+gather=samples+" + COMMON),
    ("walks, cubic", "basis=cubic+estimator=galerkin+transport=walk+control-variate=none+gather=none+" + COMMON),
    ("walks, cubic, gather", "basis=cubic+estimator=galerkin+transport=walk+control-variate=none+gather=samples+" + COMMON),
    ("walks, cubic, absorption", "basis=cubic+estimator=galerkin+transport=walk+control-variate=none+walk-score=absorption+gather=none+"
     + COMMON),
    ("walks, cubic, survival", "basis=cubic+estimator=galerkin+transport=walk+control-variate=none+walk-score=survival+gather=none+"
     + COMMON),
]
# The walks' scores (method.md, Random walks) against collision, the walks' default.
SCORES = {"walks, cubic, absorption": "absorption", "walks, cubic, survival": "survival"}
BASELINE = "shooting, cubic"
for _name in [n for n in SCENES if n not in os.environ.get("FAMILY_SCENES", ",".join(SCENES)).split(",")]:
    del SCENES[_name]


def run(args, **kw):
    return subprocess.run(args, cwd=ROOT, check=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def reference(scene, n, out):
    """`flatland reference` at resolution n into out; its wall time in seconds."""
    start = time.perf_counter()
    run([FLATLAND, "reference", SCENES[scene][0], "--elements", str(n), "--threads", THREADS, "--no-error-estimate",
         "--quiet", "--out", out])
    return time.perf_counter() - start


def l2_error(result, ref):
    out = run([FLATLAND, "compare", result, ref, "--json"]).stdout
    return json.loads(out)["scene"]["l2"]


def samples_by(rows):
    """label -> budget -> [(error, seconds) of each seed]."""
    groups = {}
    for r in rows:
        groups.setdefault(r["method"], {}).setdefault(r["budget"], []).append((float(r["rel_l2"]), float(r["seconds"])))
    return groups


def medians(samples):
    """label -> budget -> (median error, median seconds), from samples_by."""
    return {m: {b: (statistics.median(e for e, _ in runs), statistics.median(t for _, t in runs)) for b, runs in by.items()}
            for m, by in samples.items()}


def time_to(points, target):
    """Log-log interpolated time at which the (time, error) curve first reaches target; None if never."""
    points = sorted(points)
    for (t0, e0), (t1, e1) in zip(points, points[1:]):
        if e0 <= target:
            return t0
        if e1 <= target:
            f = math.log(e0 / target) / math.log(e0 / e1)
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return points[0][0] if points and points[0][1] <= target else None


def seconds_text(t, limit):
    if t is None:
        return "> %.2g s" % limit
    return "%.2g s" % t


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--tables", default=os.path.join(ROOT, "docs", "tables"))
    parser.add_argument("--out", default=os.path.join(ROOT, "build", "reproduce", "family"))
    a = parser.parse_args()
    os.makedirs(a.out, exist_ok=True)
    labels = {m: label for label, m in METHODS}
    lines = ["| scene | method | error at 1e6 | time at 1e6 | efficiency at 1e6 | time to 1 % | time to 0.1 % |",
             "|---|---|---|---|---|---|---|"]
    gains = {}  # scene class -> [gather's efficiency over shooting at 1e6]
    blocks_gains = []  # [(scene, blocks' efficiency over shooting at 1e6)]
    jacobi_gains = []  # [(scene, averaged Jacobi iterations' efficiency over shooting at 1e6)]
    variate_gains = []  # [(scene, the coarse control variate's efficiency over shooting at 1e6)]
    gathered_variate_gains = []  # [(scene, the same under the gather over the gather alone)]
    score_gains = {}  # score -> [(scene, its efficiency over collision-scored walks at 1e6)]
    reference_wins = []
    for scene, (path, kind, n) in SCENES.items():
        folder = os.path.join(a.out, scene)
        os.makedirs(folder, exist_ok=True)
        fine = os.path.join(folder, "reference.json")
        fine_seconds = reference(scene, n, fine)
        print("%s: fine reference (N = %d) in %.1f s" % (scene, n, fine_seconds), flush=True)
        ref_points = []
        with open(os.path.join(folder, "reference-times.csv"), "w") as f:
            f.write("resolution,seconds,rel_l2\n")
            for r in REFERENCE_RESOLUTIONS:
                coarse = os.path.join(folder, "reference-%d.json" % r)
                t = reference(scene, r, coarse)
                e = l2_error(coarse, fine)
                ref_points.append((t, max(e, 1e-300)))
                f.write("%d,%.6g,%.6g\n" % (r, t, e))
        run([FLATLAND, "converge", path, "--reference", fine, "--methods", ",".join(m for _, m in METHODS),
             "--budgets", ",".join(BUDGETS), "--seeds", str(SEEDS), "--threads", THREADS, "--tolerance", "1e-6",
             "--out", folder])
        rows = list(csv.DictReader(open(os.path.join(folder, "convergence.csv"))))
        for r in rows:
            r["method"] = labels[r["method"]]
            # The budget a run was given: the nearest of BUDGETS to the photons it shot.
            r["budget"] = min(BUDGETS, key=lambda b: abs(math.log(float(b)) - math.log(max(1.0, float(r["photons"])))))
        samples = samples_by(rows)
        med = medians(samples)
        fixed = min(BUDGETS, key=lambda b: abs(float(b) - FIXED))
        base = med[BASELINE].get(fixed)
        largest = max(t for by in med.values() for _, t in by.values())
        for label, _ in METHODS:
            by = med[label]
            at = by.get(fixed)
            exact = at[0] < ROUND_OFF  # the reference's own answer to round-off: no efficiency to speak of
            eff = (base[0] ** 2 * base[1]) / (at[0] ** 2 * at[1]) if not exact else math.inf
            if label == "shooting, cubic, gather":
                gains.setdefault(kind, []).append((scene, eff))
            if label == "shooting, cubic, blocks":
                blocks_gains.append((scene, eff))
            if label == "jacobi, cubic":
                jacobi_gains.append((scene, eff))
            if label == "shooting, cubic, coarse variate":
                variate_gains.append((scene, eff if at[0] >= VARIATE_EXACT else math.inf))
            if label == "shooting, cubic, coarse variate, gather":
                gathered = med["shooting, cubic, gather"].get(fixed)
                gathered_variate_gains.append(
                    (scene, (gathered[0] ** 2 * gathered[1]) / (at[0] ** 2 * at[1])
                     if at[0] >= VARIATE_EXACT and gathered[0] >= ROUND_OFF else math.inf))
            if label in SCORES:
                by_walks = med["walks, cubic"].get(fixed)
                score_gains.setdefault(SCORES[label], []).append(
                    (scene, (by_walks[0] ** 2 * by_walks[1]) / (at[0] ** 2 * at[1])))
            pts = [(t, e) for e, t in by.values()]
            lines.append("| %s | %s | %s | %.3g s | %s | %s | %s |" % (
                scene.replace("_", " "), label,
                spread.percent([e for e, _ in samples[label][fixed]]) if not exact else "round-off", at[1],
                "%.3gx" % eff if not exact else "exact",
                seconds_text(time_to(pts, TARGETS[0]), largest), seconds_text(time_to(pts, TARGETS[1]), largest)))
        lines.append("| %s | reference (deterministic) | | | | %s | %s |" % (
            scene.replace("_", " "), seconds_text(time_to(ref_points, TARGETS[0]), max(t for t, _ in ref_points)),
            seconds_text(time_to(ref_points, TARGETS[1]), max(t for t, _ in ref_points))))
        best_mc = min((time_to([(t, e) for e, t in med[l].values()], TARGETS[1]) or math.inf) for l, _ in METHODS)
        ref_t = time_to(ref_points, TARGETS[1]) or math.inf
        reference_wins.append((scene, ref_t < best_mc, ref_t, best_mc))
    head = ("%d seeds, budgets %s, %s threads; medians; relative L2 error of B - E against a reference finer than the "
            "gather's elements, at 1e6 photons the %s; efficiency is 1 / (error^2 x time) over progressive shooting's (cubic, no gather) at 1e6 "
            "photons; the reference's row: the coarsest `flatland reference` that reaches the error:\n\n"
            % (SEEDS, " ".join(BUDGETS), THREADS, spread.caption(SEEDS)))
    os.makedirs(a.tables, exist_ok=True)
    with open(os.path.join(a.tables, "family.md"), "w") as f:
        f.write(head + "\n".join(lines) + "\n")
    findings = []
    for kind, all_values in gains.items():
        exact = [s for s, v in all_values if math.isinf(v)]
        if exact:
            findings.append("- On %s the final gather is the reference's own answer to round-off: B - E there is "
                            "direct light only, which it computes exactly." % ", ".join(s.replace("_", " ") for s in exact))
        values = [(s, v) for s, v in all_values if not math.isinf(v)]
        if not values:
            continue
        g = math.exp(statistics.mean(math.log(v) for _, v in values))
        findings.append("- On %s scenes (%s) the final gather's efficiency over progressive shooting at 1e6 photons "
                        "has a geometric mean of %.3gx (from %.3gx to %.3gx)." % (
                            kind, ", ".join(s.replace("_", " ") for s, _ in values), g,
                            min(v for _, v in values), max(v for _, v in values)))
    for what, pairs in (("Replicates as blocks of one net (no gather) have an efficiency over independent replicates'",
                         blocks_gains),
                        ("Averaged Jacobi iterations (no gather) have an efficiency over progressive shooting's",
                         jacobi_gains),
                        ("The coarse control variate (no gather) has an efficiency over progressive shooting's",
                         variate_gains),
                        ("Under the gather, the coarse control variate has an efficiency over the gather alone",
                         gathered_variate_gains)):
        finite = [(sc, v) for sc, v in pairs if not math.isinf(v)]
        if not finite:
            continue
        exact = [sc.replace("_", " ") for sc, v in pairs if math.isinf(v)]
        g = math.exp(statistics.mean(math.log(v) for _, v in finite))
        low, high = min(finite, key=lambda p: p[1]), max(finite, key=lambda p: p[1])
        findings.append("- %s at 1e6 photons with a geometric mean of %.3gx over %d scenes (from %.3gx on %s to %.3gx "
                        "on %s)%s." % (what, g, len(finite), low[1], low[0].replace("_", " "), high[1],
                                       high[0].replace("_", " "),
                                       "; on %s its error is below %g, the projection's quadrature, not noise"
                                       % (", ".join(exact), VARIATE_EXACT) if exact else ""))
    for score, values in score_gains.items():
        g = math.exp(statistics.mean(math.log(v) for _, v in values))
        low, high = min(values, key=lambda p: p[1]), max(values, key=lambda p: p[1])
        findings.append("- Walks scored by %s have an efficiency over collision-scored walks at 1e6 walks with a "
                        "geometric mean of %.3gx over %d scenes (from %.3gx on %s to %.3gx on %s)." % (
                            score, g, len(values), low[1], low[0].replace("_", " "), high[1],
                            high[0].replace("_", " ")))
    wins = [s for s, w, _, _ in reference_wins if w]
    findings.append("- The deterministic reference reaches 0.1 %% sooner than every Monte Carlo method here on %d of %d "
                    "scenes%s." % (len(wins), len(reference_wins),
                                   (" (" + ", ".join(s.replace("_", " ") for s in wins) + ")") if wins else ""))
    with open(os.path.join(a.tables, "family-findings.md"), "w") as f:
        f.write("\n".join(findings) + "\n")
    print(open(os.path.join(a.tables, "family.md")).read())
    print("\n".join(findings))


if __name__ == "__main__":
    main()
