#!/usr/bin/env bash
# Pictures of the method's geometry for docs/storage-mesh.md, taken by flatland itself (offscreen):
# the arch on a lit floor with contacts (scene joints) and without (none), and the round occluder
# with its direct-light events (auto) and without (scene).
# Usage: [FLATLAND=PATH] docs/figures/geometry/geometry.sh [BUILD_DIR]: the program is FLATLAND (as
# docs/reproduce.sh sets it), else BUILD_DIR/flatland (BUILD_DIR defaults to build).
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-${1:-build}/flatland}
out=docs/figures/geometry
common=(--photons 2e6 --width 960 --height 600 --paths 6000 --graph --band --quiet)
"$flatland" render scenes2d/arch.json "${common[@]}" --discontinuities scene --out "$out/arch_contacts.png"
"$flatland" render scenes2d/arch.json "${common[@]}" --discontinuities none --out "$out/arch_no_contacts.png"
"$flatland" render scenes2d/tests/reference_round_occluder.json "${common[@]}" --discontinuities auto \
  --out "$out/round_occluder_auto.png" --result "$out/round_occluder_auto.json" --samples 400
"$flatland" render scenes2d/tests/reference_round_occluder.json "${common[@]}" --discontinuities scene \
  --out "$out/round_occluder_scene.png"
