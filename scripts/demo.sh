#!/usr/bin/env bash
# README command 1: install, build, generate a phantom skull, extract its endocast, and print the
# measured ECV next to the true (analytic) one. Outputs go to out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
mkdir -p out/demo
./build/bin/endocast phantom out/demo/phantom.nrrd --preset human
./build/bin/endocast extract out/demo/phantom.nrrd -o out/demo/endocast.stl \
  --mask out/demo/endocast_mask.nrrd --report out/demo/report.json
num() { sed -n "s/^  \"$1\": \([-0-9.eE+]*\).*/\1/p" "$2" | head -n1; }
true_ecv=$(num true_ecv_ml out/demo/phantom.json)
ecv=$(num ecv_ml out/demo/report.json)
awk -v m="$ecv" -v t="$true_ecv" 'BEGIN {
  printf "\nECV measured %.2f mL   true %.2f mL   error %+.2f%%\n", m, t, 100 * (m / t - 1) }'
echo "mesh: out/demo/endocast.stl   mask: out/demo/endocast_mask.nrrd   report: out/demo/report.json"
