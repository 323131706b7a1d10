#!/usr/bin/env bash
# The viewer's pictures in README.md and docs/viewer.md, taken by the viewer itself under a
# virtual X server (Mesa's software OpenGL). Run from the top of the repository after building.
set -euo pipefail
flatland=${FLATLAND:-build/flatland}
run() { xvfb-run -a -s "-screen 0 1600x1000x24" "$flatland" "$@"; }

# The window with its panels: the default scene after three rounds, one curve inspected.
run view scenes2d/default.json --frames 3 --step rounds=1 --width 1280 --height 800 \
  --screenshot-ui docs/figures/viewer.png --select screen
# The first photons of the first round on the penumbra scene: light from the emitter only.
run view scenes2d/penumbra.json --frames 2 --step photons=2000 --width 960 --height 540 --keep-paths 4000 \
  --screenshot docs/figures/viewer_first_photons.png
# Three rounds with extended rays drawn at their width, coloured by round: a small budget, so that
# every path of the three rounds stays among the kept ones.
run view scenes2d/room_reflector.json --frames 3 --step rounds=1 --width 960 --height 640 --photons 6000 \
  --keep-paths 6000 --fade 0 --ray-width 0.02 --colour-by round --screenshot docs/figures/viewer_rounds.png
# The light as a field: the mirror room's sunbeam and its reflection, one round a frame to the end
# of the solve (deterministic).
run view scenes2d/mirror_room.json --frames 12 --step rounds=1 --width 1280 --height 800 --select walls \
  --screenshot-ui docs/figures/viewer_field.png
# The teaching scenes at 1e6 photons, solved to the end one round a frame (deterministic), the
# light as a field, without panels.
for lesson in lens prism light_guide mirror_room parabolic_mirror; do
  run view scenes2d/$lesson.json --frames 40 --step rounds=1 --width 960 --height 600 \
    --screenshot docs/figures/lesson_$lesson.png
done
# flatland render: the same renderer without a display.
"$flatland" render scenes2d/mixed.json --photons 1e6 --width 960 --height 640 --out docs/figures/render_mixed.png --quiet
# Random walks stepped one photon a frame, coloured by bounce, the newest journey on top.
run view scenes2d/room_reflector.json --transport walk --frames 6 --step photons=1 --width 1280 --height 800 \
  --colour-by bounce --keep-paths 60 --exposure 0.3 --select walls --screenshot-ui docs/figures/viewer_journey.png
