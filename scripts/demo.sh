#!/usr/bin/env bash
# make demo: simulate -> inspect -> run -> report on a small log, then the same on a committed sample.
set -euo pipefail
IVSLAM="${1:?usage: demo.sh path/to/ivslam OUTDIR}"
OUT="${2:-out}"
mkdir -p "$OUT"
step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

step "1. simulate a pairs log (Mustafa, Codres & Stancu's setting: holonomic robot, range-bearing landmarks)"
"$IVSLAM" simulate --scenario pairs --seed 7 --steps 120 --landmarks 15 -o "$OUT/demo_pairs.mcap" --force

step "2. inspect it"
"$IVSLAM" inspect "$OUT/demo_pairs.mcap"

step "3. run the pairs pipeline (guaranteed displacement subpavings, relative map)"
"$IVSLAM" run "$OUT/demo_pairs.mcap" --mode pairs -o "$OUT/demo_pairs.h5" --force

step "4. report: consistency, convergence, containment of the truth"
"$IVSLAM" report "$OUT/demo_pairs.h5" --plot "$OUT/demo_pairs.png" --force
"$IVSLAM" report "$OUT/demo_pairs.h5" --json > "$OUT/demo_pairs.json"

step "5. the committed sample log (sample_logs/pairs.mcap)"
"$IVSLAM" run sample_logs/pairs.mcap --mode pairs -o "$OUT/sample_pairs.h5" --force
"$IVSLAM" report "$OUT/sample_pairs.h5" | tail -n 6

step "6. the landmark CSP on a simulated unicycle log with 1 % outliers: pose tube and landmark boxes"
"$IVSLAM" simulate --scenario landmarks --seed 3 --steps 300 --outlier-rate 0.01 -o "$OUT/demo_landmarks.mcap" --force
"$IVSLAM" run "$OUT/demo_landmarks.mcap" --mode landmarks --initial-pose-from-truth --q-landmark 2 --q-pose 1 \
    -o "$OUT/demo_landmarks.h5" --tum "$OUT/demo_landmarks.tum" --force
"$IVSLAM" report "$OUT/demo_landmarks.h5" --plot "$OUT/demo_landmarks.png" --force | tail -n 12

step "7. feature-less LiDAR SLAM in submaps: a simulated URG-04LX log (30 s), every scan tracked and mapped in its submap's frame"
"$IVSLAM" simulate --scenario lidar --world rooms --sensor urg-04lx --duration 30 --seed 5 -o "$OUT/demo_lidar.h5" --force
"$IVSLAM" run "$OUT/demo_lidar.h5" --mode lidar -o "$OUT/demo_lidar.res.h5" --force
"$IVSLAM" report "$OUT/demo_lidar.res.h5" --plot "$OUT/demo_lidar.png" --force | grep -E "containment|pose|map_free|submaps|proven free|scans mapped|SOUNDNESS"
"$IVSLAM" report "$OUT/demo_lidar.res.h5" --plot "$OUT/demo_lidar_submap0.png" --submap 0 --force > /dev/null

printf '\nDone. Results in %s/: demo_pairs.h5 / demo_landmarks.h5 / demo_lidar.res.h5 (HDF5 results), demo_pairs.png / demo_landmarks.png / demo_lidar.png / demo_lidar_submap0.png (plots), demo_pairs.json (report), demo_landmarks.tum (TUM trajectory).\n' "$OUT"
