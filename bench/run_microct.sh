#!/usr/bin/env bash
# microCT-size run of `endocast extract` (issue 17): a 2048 x 2048 x 1500 int16 macaque phantom
# (6.3 G voxels, 12.6 GB, 0.055 mm voxels) written slab by slab as raw NRRD, then extracted with
# --downsample F (read in slabs: the whole volume is never in memory). Prints a markdown row per
# factor: wall time, max RSS, ECV against the phantom's truth, mesh checks. Needs ~13 GB of disk in
# DIR (kept between runs: the phantom is written only when missing) and ~10 min to write it.
# Usage: bash bench/run_microct.sh [build-dir] [DIR] ["F1 F2 ..."]   (default factors: "8 4")
set -euo pipefail
cd "$(dirname "$0")/.."
B="$(pwd)/${1:-build}/bin/endocast"
D="${2:-/tmp/endocast-microct}"
read -r -a factors <<< "${3:-8 4}"
mkdir -p "$D"
num() { sed -n "s/^  \"$1\": \([-0-9.eE+]*\).*/\1/p" "$2" | head -n1; }
P="$D/mq2048.nrrd"
if [ ! -f "$P" ] || [ ! -f "$D/mq2048.json" ]; then
  /usr/bin/time -v "$B" phantom "$P" --preset macaque --size 2048 2048 1500 --spacing 0.055 0.055 0.055 --stream \
      2> "$D/phantom.time"
  echo "phantom: $(grep 'Elapsed' "$D/phantom.time" | sed 's/.*: //') wall, max RSS $(($(sed -n 's/.*Maximum resident set size (kbytes): //p' "$D/phantom.time") / 1024)) MB"
fi
truth=$(num true_ecv_ml "$D/mq2048.json")
echo "| input | --downsample | work grid | wall s (read) | max RSS MB | ECV mL | truth mL | error % | closed 2-manifold, genus | read path |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for f in "${factors[@]}"; do
  R="$D/ds$f.json"
  /usr/bin/time -v "$B" extract "$P" --downsample "$f" --threads 2 -q -o "$D/ds$f.ply" --report "$R" 2> "$D/ds$f.time"
  wall=$(python3 -c "import json,sys; t=json.load(open(sys.argv[1]))['timings_s']; print(t['total'], t['read'])" "$R")
  rss=$(( $(sed -n 's/.*Maximum resident set size (kbytes): //p' "$D/ds$f.time") / 1024 ))
  ecv=$(num ecv_ml "$R")
  dims=$(python3 -c "import json,sys; print(' x '.join(map(str, json.load(open(sys.argv[1]))['work_grid']['dims'])))" "$R")
  closed=$(sed -n 's/^  "closed_manifold": \(true\|false\).*/\1/p' "$R" | head -n1)
  genus=$(num genus "$R")
  path=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['input']['read_path'])" "$R")
  awk -v f="$f" -v d="$dims" -v w="${wall% *}" -v rd="${wall#* }" -v r="$rss" -v e="$ecv" -v t="$truth" -v c="$closed" -v g="$genus" -v p="$path" \
    'BEGIN { printf "| macaque phantom 2048 x 2048 x 1500 int16 (raw NRRD, 12.6 GB) | %s | %s | %.1f (%.1f) | %d | %.3f | %.3f | %+.3f | %s, %s | %s |\n", f, d, w, rd, r, e, t, 100 * (e - t) / t, c, g, p }'
done
