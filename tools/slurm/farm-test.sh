#!/usr/bin/env bash
# a farm render on a real single-node Slurm. Brings Slurm up
# (tools/slurm/up.sh), submits `phenomena farm slurm --submit` for a small flame and a
# small aurora scene in 4 chunks each, waits (bounded), checks that every job completed
# (sacct -c: job completion records, as accounting storage is off) and that every frame
# is byte-identical to a render on this machine; then reruns one task alone after
# deleting its frames and checks them again. Stops the daemons on exit.
# Usage: tools/slurm/farm-test.sh PHENOMENA_BINARY SCRATCH_DIR
set -euo pipefail
bin=$(realpath "${1:?usage: farm-test.sh PHENOMENA SCRATCH}")
work=$(realpath -m "${2:?usage: farm-test.sh PHENOMENA SCRATCH}")
here=$(cd "$(dirname "$0")" && pwd)
scenes=$(cd "$here/../../scenes" && pwd)
rm -rf "$work"
mkdir -p "$work"
trap '"$here/down.sh" "$work/slurm"' EXIT
export SLURM_CONF=$("$here/up.sh" "$work/slurm")

# name, shipped scene, frames, chunk
cases=("flame flame-paper 24 6" "aurora aurora-scene2 16 4")
for c in "${cases[@]}"; do
  read -r name file frames chunk <<<"$c"
  sed "s/^frames = .*/frames = $frames/" "$scenes/$file.toml" > "$work/$name.toml"
  "$bin" farm slurm "$work/$name.toml" --out "$work/$name-farm" --chunk "$chunk" \
    --width 160 --height 90 --submit | tee "$work/$name-submit.txt"
done

# Wait until the queue is empty (bounded: 15 minutes).
for i in $(seq 1 900); do
  [ -z "$(squeue -h)" ] && break
  if [ "$i" = 900 ]; then echo "farm jobs still queued after 15 minutes:" >&2; squeue >&2; exit 1; fi
  sleep 1
done
echo "== job completion records (sacct -c; accounting storage is off, jobcomp/filetxt is on)"
sacct -c --format=JobID,JobName%30,State,ExitCode 2>/dev/null
# 2 simulation jobs and 8 render tasks, each recorded once by the job completion plugin.
records="$work/slurm/log/jobcomp.txt"
done_ok=$(grep -c 'JobState=COMPLETED' "$records" || true)
bad=$(grep -vc 'JobState=COMPLETED' "$records" || true)
if [ "$done_ok" != 10 ]; then
  echo "expected 10 completed farm jobs, found $done_ok" >&2
  bad=1
fi
if [ "$bad" != 0 ]; then
  echo "$bad farm job(s) did not complete; logs:" >&2
  tail -n 20 "$work"/*-farm/farm/logs/* >&2
  exit 1
fi

compare() { # farm frames dir, local frames dir, expected count
  local n=0
  for f in "$2"/frame_*.png; do
    cmp -s "$f" "$1/$(basename "$f")" || { echo "FAIL: $1/$(basename "$f") differs from the local render" >&2; exit 1; }
    n=$((n + 1))
  done
  [ "$n" = "$3" ] || { echo "FAIL: $n local frames, expected $3" >&2; exit 1; }
  [ "$(ls "$1" | grep -c '^frame_')" = "$3" ] || { echo "FAIL: the farm wrote $(ls "$1" | wc -l) files, expected $3" >&2; exit 1; }
}
for c in "${cases[@]}"; do
  read -r name file frames chunk <<<"$c"
  "$bin" render "$work/$name.toml" --out "$work/$name-local" --width 160 --height 90 >/dev/null
  compare "$work/$name-farm/frames" "$work/$name-local" "$frames"
  echo "$name: $frames farm frames in $((frames / chunk)) tasks are byte-identical to the local render"
done

# A lost chunk is rerun alone: task 2 of the aurora, from its checkpoint.
rm "$work"/aurora-farm/frames/frame_0000{8,9}.png "$work"/aurora-farm/frames/frame_0001{0,1}.png
sbatch --wait --array=2 "$work/aurora-farm/farm/render.sbatch" >/dev/null
compare "$work/aurora-farm/frames" "$work/aurora-local" 16
grep -q "started from the checkpoint at frame 8" "$work"/aurora-farm/farm/logs/render-*_2.out
echo "aurora: task 2 rerun alone from its checkpoint gives the same bytes"
echo "farm test passed"
