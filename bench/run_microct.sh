#!/usr/bin/env bash
# microCT-size run of `endocast extract` (issue 17): a 2048 x 2048 x 1500 int16 macaque phantom
# (6.3 G voxels, 12.6 GB, 0.055 mm voxels) written slab by slab as raw NRRD, then extracted at full
# resolution (the memory guard takes the coarse-to-fine path) and with --downsample F (read in
# slabs: the whole volume is never in memory). Prints a markdown row per run: wall time, max RSS,
# ECV against the phantom's truth, mesh checks, and for the downsampled runs the mean and largest
# distance to the full-resolution mesh (`endocast compare`). Needs ~14 GB of disk in DIR (kept
# between runs: the phantom is written only when missing), ~3-10 min to write it, and ~20 GB of
# memory for --downsample 2.
# Usage: bash bench/run_microct.sh [build-dir] [DIR] ["F1 F2 ..."]   (default factors: "4 2")
set -euo pipefail
cd "$(dirname "$0")/.."
B="$(pwd)/${1:-build}/bin/endocast"
D="${2:-/tmp/endocast-microct}"
read -r -a factors <<< "${3:-4 2}"
mkdir -p "$D"
num() { sed -n "s/^  \"$1\": \([-0-9.eE+]*\).*/\1/p" "$2" | head -n1; }
P="$D/mq2048.nrrd"
if [ ! -f "$P" ] || [ ! -f "$D/mq2048.json" ]; then
  /usr/bin/time -v "$B" phantom "$P" --preset macaque --size 2048 2048 1500 --spacing 0.055 0.055 0.055 --stream \
      2> "$D/phantom.time"
  echo "phantom: $(grep 'Elapsed' "$D/phantom.time" | sed 's/.*: //') wall, max RSS $(($(sed -n 's/.*Maximum resident set size (kbytes): //p' "$D/phantom.time") / 1024)) MB"
fi
truth=$(num true_ecv_ml "$D/mq2048.json")
# Full resolution: no --downsample; the memory guard takes the coarse-to-fine path (report: path).
/usr/bin/time -v "$B" extract "$P" --threads 2 -q -o "$D/full.ply" --report "$D/full.json" 2> "$D/full.time"
echo "| input | --downsample | path | mesh grid | wall s (read, refine, check) | max RSS MB | ECV mL | truth mL | error % | closed 2-manifold, genus, self-intersections | faces | mean / max distance to the full-resolution mesh, mm |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
row() {  # $1 = name of the run, $2 = factor shown
  local R="$D/$1.json"
  local rss=$(( $(sed -n 's/.*Maximum resident set size (kbytes): //p' "$D/$1.time") / 1024 ))
  local dist="-"
  if [ "$1" != full ]; then
    "$B" compare "$D/$1.ply" "$D/full.ply" --report "$D/cmp_$1.json" > /dev/null
    dist=$(python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print('%.4f / %.3f' % ((j['a_to_b']['mean'] + j['b_to_a']['mean']) / 2, j['hausdorff']))" "$D/cmp_$1.json")
  fi
  python3 - "$R" "$2" "$rss" "$truth" "$dist" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); t = j['timings_s']
truth = float(sys.argv[4]); e = j['ecv_ml']
print('| macaque phantom 2048 x 2048 x 1500 int16 (raw NRRD, 12.6 GB) | %s | %s | %s | %.1f (%.1f, %.1f, %.1f) | %s | %.3f | %.3f | %+.3f | %s, %d, %d | %d | %s |' % (
    sys.argv[2], j['path'], ' x '.join(map(str, j['work_grid']['dims'])), t['total'], t['read'], t.get('refine', 0), t['check'],
    sys.argv[3], e, truth, 100 * (e - truth) / truth, str(j['closed_manifold']).lower(), j['genus'], j['self_intersections'],
    j['faces'], sys.argv[5]))
PY
}
row full 1
for f in "${factors[@]}"; do
  /usr/bin/time -v "$B" extract "$P" --downsample "$f" --threads 2 -q -o "$D/ds$f.ply" --report "$D/ds$f.json" 2> "$D/ds$f.time"
  row "ds$f" "$f"
done
