#!/usr/bin/env python3
"""The default path before and after `--control-variate auto` became solve's default, side by side.

Per scene: a fine reference (`flatland reference`, as docs/figures/family/run.py makes it), then
`flatland converge` of two methods in one run, interleaved seed by seed: `control-variate=none`
(the default before) and `control-variate=auto` (the default now), every other setting at the
program's defaults (cubic storage, the final gather where --gather auto takes it, tolerance 1e-3).
Prints a Markdown table: the median relative L2 error of B - E at the budget, the median time
(with the variate's set-up and the gather), the efficiency 1 / (error^2 x time) of auto over none,
and what auto chose.

  bench/default_variate.py --out /tmp/default-variate [--flatland build/flatland] [--photons 1e6]
                           [--seeds 3] [--scenes office,window_room]
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
# name -> (scene file, resolution of the fine reference), as the family's tables.
SCENES = {
    "penumbra": ("scenes2d/penumbra.json", 800),
    "round_occluder": ("scenes2d/tests/reference_round_occluder.json", 1600),
    "ring_profile": ("scenes2d/tests/reference_ring_profile.json", 800),
    "curved_room": ("scenes2d/curved_room.json", 1600),
    "default": ("scenes2d/default.json", 1200),
    "office": ("scenes2d/interreflection/office.json", 1200),
    "window_room": ("scenes2d/interreflection/window_room.json", 1200),
    "row_of_rooms": ("scenes2d/row_of_rooms.json", 1200),
}
METHODS = ["control-variate=none", "control-variate=auto"]
ROUND_OFF = 1e-10


def run(command):
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(command), done.stderr))
    return done.stdout


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--flatland", default="build/flatland")
    parser.add_argument("--photons", default="1e6")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--threads", default="2")
    parser.add_argument("--scenes", default=",".join(SCENES))
    args = parser.parse_args()
    flatland = os.path.abspath(args.flatland) if os.path.exists(args.flatland) else args.flatland
    rows = []
    for name in args.scenes.split(","):
        if name not in SCENES:
            sys.exit("--scenes: no scene '%s'; the scenes are %s" % (name, ", ".join(SCENES)))
        path, n = SCENES[name]
        folder = os.path.join(os.path.abspath(args.out), name)
        os.makedirs(folder, exist_ok=True)
        reference = os.path.join(folder, "reference.json")
        if not os.path.exists(reference):
            run([flatland, "reference", path, "--elements", str(n), "--threads", args.threads,
                 "--no-error-estimate", "--quiet", "--out", reference])
        run([flatland, "converge", path, "--reference", reference, "--methods", ",".join(METHODS),
             "--budgets", args.photons, "--seeds", str(args.seeds), "--threads", args.threads, "--out", folder])
        table = list(csv.DictReader(open(os.path.join(folder, "convergence.csv"))))
        medians = {}
        for method in METHODS:
            mine = [r for r in table if r["method"] == method]
            medians[method] = (statistics.median(float(r["rel_l2"]) for r in mine),
                               statistics.median(float(r["seconds"]) for r in mine))
        # What auto chose: one solve's result says it (settings.control_variate).
        result = os.path.join(folder, "auto.json")
        run([flatland, "solve", path, "--photons", "1e4", "--threads", args.threads, "--quiet", "--out", result])
        variate = json.load(open(result))["settings"].get("control_variate", {})
        chose = variate.get("kind", "none") if "skipped" not in variate else "none (%s)" % variate["skipped"]
        (e0, t0), (e1, t1) = medians[METHODS[0]], medians[METHODS[1]]
        # Below ROUND_OFF both answers are the reference's own to round-off (the gather of direct
        # light): an efficiency would compare round-off.
        gain = (e0 * e0 * t0) / (e1 * e1 * t1) if min(e0, e1) > ROUND_OFF else None
        rows.append((name, e0, t0, e1, t1, gain, chose))
        print("%s done" % name, file=sys.stderr)
    lines = ["| scene | error before (none) | time before | error now (auto) | time now | efficiency now / before | auto chose |",
             "|---|---|---|---|---|---|---|"]
    for name, e0, t0, e1, t1, gain, chose in rows:
        lines.append("| %s | %.2g %% | %.3f s | %.2g %% | %.3f s | %s | %s |"
                     % (name, 100 * e0, t0, 100 * e1, t1, "round-off" if gain is None else "%.3gx" % gain, chose))
    text = "\n".join(lines) + "\n"
    open(os.path.join(os.path.abspath(args.out), "default-variate.md"), "w").write(text)
    print(text)


if __name__ == "__main__":
    main()
