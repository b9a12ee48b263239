#!/usr/bin/env bash
# Regenerates docs/validate/scenes/ (about 10 min on 2 cores): the three scenes at the
# prototype's pixel scale, then the soccer ball at three speeds and three defocus radii
# (a design covering 1 px/ms at the ball's 1000 mm). The EXR layers are left out of git.
set -euo pipefail
cd "$(dirname "$0")"
PACAM=${PACAM:-pacam}
for scene in train soccer walker; do
  $PACAM validate-scene "$scene" --out "$scene" --force --quiet
done
design=(--depth 1000 --cover 1.0)
for v in 0.5 1.0 2.0; do
  $PACAM validate-scene soccer "${design[@]}" --r-px 2 --speed "$v" --out "soccer_v$v" --force --quiet
done
for r in 1 4; do
  $PACAM validate-scene soccer "${design[@]}" --r-px "$r" --speed 1.0 --out "soccer_r$r" --force --quiet
done
rm -f ./*/validate_scene.exr
