#!/usr/bin/env python3
"""The headless photon rate of the viewer's own solve: the same scene and budget (1e9 photons,
tolerance 1e-12: what `flatland view` solves), stepped 2e6 photons at a time for SECONDS of
shooting, on every core.

    PYTHONPATH=build/python python3 docs/figures/headless_rate.py scenes2d/default.json 6
"""
import sys

import flatland

scene = flatland.Scene.load(sys.argv[1])
solver = flatland.Solver(scene, photons=int(1e9), tolerance=1e-12, threads=0)
while solver.stats["seconds"] < float(sys.argv[2]):
    solver.step_photons(2_000_000)
stats = solver.stats
print(f"headless, same budget: {stats['photons'] / stats['seconds'] / 1e6:.2f} M photons/s "
      f"over {stats['seconds']:.1f} s")
