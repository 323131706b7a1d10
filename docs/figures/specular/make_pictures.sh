#!/bin/sh
# The teaching scenes with mirrors, glass and a prism (docs/experiments-error-and-optics.md,
# "Mirrors, glass and dispersion"): each rendered by `flatland render` (photon paths and B along
# the curves, no display needed). FLATLAND selects the executable (default build/flatland); run
# from the repository's top.
set -eu
flatland=${FLATLAND:-build/flatland}
out=docs/figures/specular
for scene in lens parabolic_mirror prism light_guide mirror_room; do
  "$flatland" render "scenes2d/$scene.json" --photons 1e6 --seed 1 --width 800 --height 500 --paths 8000 --out "$out/$scene.png"
done
