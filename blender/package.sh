#!/usr/bin/env bash
# Package the add-on as a Blender 4.2+ extension: the phenomena wheel (built from
# python/ with pip and maturin) goes in phenomena_blender/wheels/, the manifest names it,
# and the folder is zipped to OUT (default target/phenomena_blender-0.1.0.zip). Install
# the zip in Blender 4.2+ with Preferences > Get Extensions > Install from Disk.
# Blender 3.4-4.1 take the folder itself as a legacy add-on (see README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/phenomena_blender-0.1.0.zip}
python=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# WHEEL: a phenomena wheel already built (else one is built here).
if [ -n "${WHEEL:-}" ]; then
  mkdir -p "$work/wheels" && cp "$WHEEL" "$work/wheels/"
else
  "$python" -m pip wheel --no-deps ./python -w "$work/wheels"
fi
wheel=$(basename "$(ls "$work"/wheels/phenomena-*.whl)")
cp -r blender/phenomena_blender "$work/phenomena_blender"
rm -rf "$work/phenomena_blender/_vendor" "$work/phenomena_blender/__pycache__"
mkdir -p "$work/phenomena_blender/wheels"
cp "$work/wheels/$wheel" "$work/phenomena_blender/wheels/"
sed -i "s|^wheels = .*|wheels = [\"./wheels/$wheel\"]|" "$work/phenomena_blender/blender_manifest.toml"
mkdir -p "$(dirname "$out")"
(cd "$work/phenomena_blender" && "$python" -m zipfile -c "$work/extension.zip" .)
mv "$work/extension.zip" "$out"
echo "wrote $out (with $wheel)"
