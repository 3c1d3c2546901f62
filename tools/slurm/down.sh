#!/usr/bin/env bash
# Stop the Slurm daemons tools/slurm/up.sh DIR started (by their pid files), and munged.
set -uo pipefail
dir=$(realpath -m "${1:?usage: down.sh DIR}")
for pid in "$dir/run/slurmd.pid" "$dir/run/slurmctld.pid"; do
  [ -s "$pid" ] && kill "$(cat "$pid")" 2>/dev/null
done
# Daemons of this folder whose pid files were lost.
pkill -f -- "-f $dir/slurm.conf" 2>/dev/null
for _ in $(seq 1 20); do
  pgrep -x slurmd >/dev/null || pgrep -x slurmctld >/dev/null || break
  sleep 0.5
done
pkill -x munged 2>/dev/null
for _ in $(seq 1 20); do
  pgrep -x munged >/dev/null || break
  sleep 0.5
done
exit 0
