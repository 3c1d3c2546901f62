#!/usr/bin/env bash
# Digest of what every shipped scene renders: the first frames of each scene at a small
# size in every format the scene writes, one SHA-256 per file. Run it before and after
# a change that must not move a pixel (a refactor) and compare the two lists:
#   tools/frames-digest/run.sh target/release/phenomena /tmp/before > before.txt
#   ... change ...
#   tools/frames-digest/run.sh target/release/phenomena /tmp/after > after.txt
#   diff before.txt after.txt
# Usage: run.sh PHENOMENA_BINARY SCRATCH_DIR [FRAMES (default 12)]
set -euo pipefail
bin=$(realpath "${1:?usage: run.sh PHENOMENA SCRATCH [FRAMES]}")
work=$(realpath -m "${2:?usage: run.sh PHENOMENA SCRATCH [FRAMES]}")
frames=${3:-12}
scenes=$(cd "$(dirname "$0")/../../scenes" && pwd)
rm -rf "$work"
mkdir -p "$work"
for scene in "$scenes"/*.toml; do
  name=$(basename "$scene" .toml)
  for format in png exr vdb ply flipbook; do
    out="$work/$name/$format"
    # A format the phenomenon does not write is refused: skip it.
    if "$bin" render "$scene" --out "$out" --frames "0..$frames" --width 160 --height 90 \
      --format "$format" >/dev/null 2>"$work/$name-$format.err"; then
      (cd "$work" && find "$name/$format" -type f ! -name '*.tmp' | sort | xargs sha256sum)
    elif ! grep -q "are not written as" "$work/$name-$format.err"; then
      echo "$name $format: failed: $(cat "$work/$name-$format.err")"
    fi
  done
done
