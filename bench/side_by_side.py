#!/usr/bin/env python3
"""Two builds of flatland side by side: error at equal photons and time per photon.

The standard for a change to the default path: the same scenes, budgets and seeds solved by the
build before (--before) and after (--after), runs interleaved (before, after, before, ...) so that
the machine's drift falls on both alike. Per scene and budget it prints the median over the seeds
of the true relative error of B - E against the scene's reference (`flatland compare`), of the
solve's own estimated bound and of its time, for both builds, and the ratios after / before
(error and bound: medians of the per-seed ratios; time: ratio of the medians).

  bench/side_by_side.py --before OLD/flatland --after build/flatland --out /tmp/ab \\
      [--scenes penumbra,curved_room] [--photons 1e6] [--seeds 3] [--threads 2] [-- SOLVE OPTIONS]

Scenes are names in scenes2d/ (or paths); references are computed once into --out.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def scene_path(name):
    for candidate in (name, os.path.join(ROOT, "scenes2d", name + ".json"),
                      os.path.join(ROOT, "scenes2d", name)):
        if os.path.isfile(candidate):
            return candidate
    sys.exit(f"side_by_side.py: no scene '{name}' (a path, or a name in scenes2d/)")


def run(command):
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"side_by_side.py: {' '.join(command)} failed: {done.stderr.strip()}")
    return done.stdout


def ratio_text(rows, key):
    """The median over the seeds of after / before, or "round-off" where some seed's error before is
    at round-off (below 1e-12 relative: a scene the method solves exactly, such as the penumbra
    under the final gather), where the ratio measures nothing."""
    pairs = list(zip(rows["after"], rows["before"]))
    if any(not b[key] > 1e-12 for _, b in pairs):
        return "round-off" if all(b[key] <= 1e-12 for _, b in pairs) else "n/a"
    return f"{statistics.median(a[key] / b[key] for a, b in pairs):.2f}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", required=True, help="the build before the change")
    parser.add_argument("--after", required=True, help="the build after the change")
    parser.add_argument("--out", required=True, help="directory for references and results")
    parser.add_argument("--scenes", default="penumbra,tests/reference_ring_profile,curved_room,default")
    parser.add_argument("--photons", default="1e6", help="budgets, comma-separated")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--measure", default="l2", choices=["l1", "l2", "linf"])
    parser.add_argument("extra", nargs="*", help="options for both solves (after --)")
    args = parser.parse_args()
    for binary in (args.before, args.after):
        if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
            sys.exit(f"side_by_side.py: {binary}: not an executable; give the flatland binary")
    if args.seeds < 1:
        sys.exit("side_by_side.py: --seeds: at least 1")
    os.makedirs(args.out, exist_ok=True)
    budgets = [b.strip() for b in args.photons.split(",") if b.strip()]
    print(f"before: {args.before}\nafter:  {args.after}\noptions: {' '.join(args.extra) or '(defaults)'}; "
          f"{args.seeds} seeds; {args.threads} threads; error: relative {args.measure.upper()} of B - E")
    header = ("| scene | photons | true before | true after | ratio | bound before | bound after | ratio "
              "| seconds before | seconds after | ratio |")
    print(header)
    print("|" + "---|" * 11)
    for name in [s.strip() for s in args.scenes.split(",") if s.strip()]:
        scene = scene_path(name)
        tag = os.path.basename(scene).removesuffix(".json")
        reference = os.path.join(args.out, f"reference_{tag}.json")
        if not os.path.isfile(reference):
            run([args.after, "reference", scene, "--out", reference, "--quiet"])
        for photons in budgets:
            rows = {"before": [], "after": []}
            for seed in range(1, args.seeds + 1):
                for which, binary in (("before", args.before), ("after", args.after)):
                    out = os.path.join(args.out, f"{tag}_{photons}_{seed}_{which}.json")
                    start = time.perf_counter()
                    run([binary, "solve", scene, "--photons", photons, "--seed", str(seed), "--threads",
                         str(args.threads), "--quiet", "--out", out] + args.extra)
                    wall = time.perf_counter() - start
                    errors = json.loads(run([args.before, "compare", out, reference, "--json"]))
                    result = json.load(open(out))
                    estimate = result["stats"].get("estimated_error") or {}
                    rows[which].append({
                        "true": errors["scene"][args.measure],
                        "bound": estimate.get(args.measure, float("nan")) if estimate.get("available") else float("nan"),
                        "seconds": result["stats"].get("seconds", wall),
                    })
            med = {w: {k: statistics.median(r[k] for r in rows[w]) for k in ("true", "bound", "seconds")}
                   for w in rows}
            ratio_true = ratio_text(rows, "true")
            ratio_bound = ratio_text(rows, "bound")
            print(f"| {tag} | {photons} | {med['before']['true']:.3e} | {med['after']['true']:.3e} | {ratio_true} "
                  f"| {med['before']['bound']:.3e} | {med['after']['bound']:.3e} | {ratio_bound} "
                  f"| {med['before']['seconds']:.3f} | {med['after']['seconds']:.3f} "
                  f"| {med['after']['seconds'] / med['before']['seconds']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
