#!/usr/bin/env python3
"""Where a photon's time goes, per scene class (docs/performance.md, "By scene class").

For each scene: `perf record` of one `flatland solve` on one thread, then `perf report --sort
symbol`, each function's share of the samples put in one part of a photon's work by its name
(PARTS below; the first pattern that matches wins), and the parts' shares turned into nanoseconds
a photon with the whole command's CPU time (perf's cpu-clock event count, in nanoseconds; so
reading the scene, building the storage, the estimated error and writing the result are in "the
rest", except set-up functions whose names match a part, such as the tree's build under the
cast). Prints a Markdown table.

  bench/photon_profile.py [--flatland build/flatland] [--photons 2e6] [--runs 3]

Needs `perf` (linux-perf) and kernel.perf_event_paranoid <= 2. With --runs R each scene is solved
R times and the run with the median time gives the shares and the time.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

SCENES = [  # (class, scene)
    ("direct light (lines)", "scenes2d/penumbra.json"),
    ("room of cubics", "scenes2d/curved_room.json"),
    ("interreflection", "scenes2d/interreflection/office.json"),
    ("glass and spectra", "scenes2d/prism.json"),
    ("mirrors", "scenes2d/mirror_room.json"),
]
# (part, pattern of the demangled function name); the first match wins, the rest is "the rest".
PARTS = [
    ("specular chains", r"follow_chain|channel_shares|EmitterSpectrum"),
    ("the cast", r"intersect_|closest_hit|bracketed_root|quadratic_roots|cubic_roots|LineGrid|line_grid|"
                 r"SegmentAccelerator|^flatland::evaluate$|hull"),
    ("the origin and direction", r"BasisSampler|sample_simplex|sample_.*origin|derivative|scramble|Sobol|"
                                 r"DiscreteDistribution|leaving_direction|sin_cos|speed_bound"),
    ("the deposit", r"SplineBasis|find_span|receive|footprint|gauss_length|arc_length|ArcLengthTable"),
    ("the loop", r"shoot_rays|PhotonShooter::shoot|side_hit"),
]
ORDER = [p for p, _ in PARTS] + ["the rest (rounds, set-up, estimate)"]


def profile(flatland, scene, photons, directory):
    data = os.path.join(directory, "perf.data")
    out = os.path.join(directory, "result.json")
    subprocess.run(["perf", "record", "-q", "-e", "cpu-clock", "-o", data, "--", flatland, "solve", scene,
                    "--photons", photons, "--threads", "1", "--gather", "none", "--control-variate", "none", "--quiet", "--out", out],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    report = subprocess.run(["perf", "report", "-i", data, "--no-children", "--sort", "symbol", "--stdio"],
                            check=True, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True).stdout
    count = re.search(r"Event count \(approx\.\): (\d+)", report)
    if not count:
        sys.exit("perf report gave no event count for " + scene)
    seconds = int(count.group(1)) * 1e-9  # cpu-clock counts nanoseconds
    shares = dict.fromkeys(ORDER, 0.0)
    for line in report.splitlines():
        match = re.match(r"\s*([0-9.]+)%\s+\[[.k]\]\s+(.*?)\s*$", line)
        if not match:
            continue
        share, name = float(match.group(1)), match.group(2)
        part = next((p for p, pattern in PARTS if re.search(pattern, name)), ORDER[-1])
        shares[part] += share
    return seconds, shares


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--flatland", default=os.environ.get("FLATLAND", "build/flatland"))
    parser.add_argument("--photons", default="2e6")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    photons = float(args.photons)
    rows = []
    for kind, scene in SCENES:
        runs = []
        for _ in range(args.runs):
            with tempfile.TemporaryDirectory() as directory:
                runs.append(profile(args.flatland, scene, args.photons, directory))
        runs.sort(key=lambda r: r[0])
        seconds, shares = runs[len(runs) // 2]
        times = [r[0] for r in runs]
        per_photon = seconds / photons * 1e9
        rows.append((kind, scene, per_photon, shares))
        print(f"{scene}: {per_photon:.0f} ns a photon (runs {', '.join('%.3f s' % t for t in times)})",
              file=sys.stderr)
    lines = ["| part of a photon (ns, share) | " + " | ".join(f"{k} (`{os.path.basename(s)}`)" for k, s, *_ in rows)
             + " |", "|---|" + "---|" * len(rows)]
    for part in ORDER:
        lines.append(f"| {part} | " + " | ".join(
            f"{p * sh[part] / 100:.0f} ({sh[part]:.0f} %)" for _, _, p, sh in rows) + " |")
    lines.append("| **a photon** | " + " | ".join(f"**{p:.0f}**" for _, _, p, _ in rows) + " |")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
