#!/usr/bin/env bash
# The snow renderer beside Blender Cycles (issue 40): the village after six hours of
# snow (fog off: Cycles is given no fog), exported as one GLB with the camera and the
# sun, rendered by us and by Cycles at 192x108, compared by SSIM (compare.py).
#   tools/cycles-ref/run.sh PHENOMENA_BINARY OUT_DIR
set -euo pipefail
bin=$1
out=$2
# The floor: the match measured 0.949 here (2026-12-05, Blender 3.4.1; a sun from the
# wrong side, [0.4, 1, -0.3] for ours only, read 0.827).
floor=${CYCLES_SSIM_FLOOR:-0.9}
mkdir -p "$out"
sed 's/^fog_per_m = .*/fog_per_m = 0.0/' scenes/snow-village.toml >"$out/village.toml"
"$bin" export snow-scene "$out/village.toml" --out "$out/village.glb"
"$bin" render "$out/village.toml" --frames 59..60 --width 192 --height 108 --out "$out/ours"
blender -b --python-exit-code 1 --python tools/cycles-ref/compare.py -- \
  "$out/village.glb" "$out/ours/frame_00059.png" "$out" 192 108 "$floor"
