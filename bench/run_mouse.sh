#!/usr/bin/env bash
# Mouse microCT: `endocast batch` over the shared mouse scans (../shared/data/mouse-microct), timed,
# at -j 1 and -j 2 (the batch's wall time, the slowest specimen, the peak memory of one), then the
# accuracy table against the expert label carried by landmarks (build/tests/mouse_table) and the
# template against its own label. Prints markdown for docs/benchmarks.md and docs/accuracy.md.
#
#   bash bench/run_mouse.sh [BUILD_DIR=build]      (from the repository root)
set -euo pipefail
BUILD=${1:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN="$ROOT/$BUILD/bin/endocast"
TABLE="$ROOT/$BUILD/tests/mouse_table"
DATA="$ROOT/../shared/data/mouse-microct"
[ -x "$BIN" ] && [ -x "$TABLE" ] || { echo "build first: $BIN and $TABLE" >&2; exit 2; }
[ -d "$DATA/scans" ] || { echo "no $DATA" >&2; exit 2; }
WORK=$(mktemp -d /tmp/endocast-mouse.XXXXXX)
trap 'rm -rf "$WORK"' EXIT

echo "| batch | scans | wall s | slowest scan s | peak memory of a scan MB |"
echo "|---|---|---|---|---|"
for j in 1 2; do
    start=$(date +%s.%N)
    "$BIN" batch "$DATA"/scans/*.nii.gz -o "$WORK/j$j" --masks -j "$j" > "$WORK/j$j.log" 2>&1
    end=$(date +%s.%N)
    python3 - "$WORK/j$j" "$j" "$start" "$end" <<'PY'
import glob, json, sys
d, j, t0, t1 = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
reps = [json.load(open(f)) for f in glob.glob(d + "/*/report.json")]
slow = max(r["timings_s"]["total"] for r in reps)
mem = max(r["peak_memory_mb"] for r in reps)
print(f"| `endocast batch scans/*.nii.gz -o OUT --masks -j {j}` | {len(reps)} | {t1 - t0:.1f} | {slow:.2f} | {mem:.0f} |")
PY
done
echo
"$BIN" -q extract "$DATA/template/low_res_template_UCHAR.nii.gz" -o "$WORK/t.ply" --mask "$WORK/t.nii.gz" \
    --report "$WORK/t.json"
"$TABLE" "$DATA" "$WORK/j2" "$WORK/t.nii.gz" "$WORK/t.json"
