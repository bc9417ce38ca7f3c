#!/usr/bin/env bash
# Regenerate the committed sample logs. Usage: make_samples.sh IVSLAM_EXECUTABLE
# (the Makefile target `sample-logs` passes .venv/bin/ivslam). Deterministic (--seed).
set -euo pipefail
IVSLAM="${1:?usage: $0 path/to/ivslam}"
case "$IVSLAM" in */*) IVSLAM="$(cd "$(dirname "$IVSLAM")" && pwd)/$(basename "$IVSLAM")" ;; esac
cd "$(dirname "$0")"
"$IVSLAM" simulate --scenario pairs --seed 1 --steps 150 --landmarks 25 -o pairs.mcap --force
"$IVSLAM" simulate --scenario landmarks --seed 2 --steps 400 --landmarks 40 --outlier-rate 0.01 \
    --wrong-association-rate 0.01 -o landmarks.bag --force
"$IVSLAM" simulate --scenario lidar --world rooms --sensor urg-04lx --seed 3 --steps 60 -o lidar_rooms.h5 --force
"$IVSLAM" simulate --scenario lidar --world corridor --sensor sick --seed 4 --steps 100 -o lidar_corridor.mcap --force
