#!/usr/bin/env bash
# Times `endocast simplify` (and the checks) on the CThead endocast: extract at iso 1300, simplify to
# 10 %, print the report's numbers. Usage: bench/run_meshcmds.sh [BUILD_DIR] (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN="${1:-build}/bin/endocast"
DATA=../shared/data/cthead/cthead.nhdr
[ -f "$DATA" ] || { echo "run_meshcmds: $DATA not found: skipped"; exit 0; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
"$BIN" extract "$DATA" --iso 1300 -q -o "$T/c.ply"
for threads in 1 2; do
  "$BIN" --threads "$threads" simplify "$T/c.ply" -o "$T/s.ply" --ratio 0.1 --report "$T/s.json" -q
  python3 - "$T/s.json" "$threads" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
t = j["timings_s"]
print(f"threads {sys.argv[2]}: faces {j['faces_before']} -> {j['faces_after']}, volume change "
      f"{j['volume_change_pct']:+.3f} %, Hausdorff {j['hausdorff_mm']:.3f} mm "
      f"(+- {j['hausdorff_sampling_error_bound_mm']:.3f}), self-intersections {j['self_intersections']}; "
      f"simplify+checks {t['simplify_and_check']:.2f} s, hausdorff {t['hausdorff']:.2f} s, total {t['total']:.2f} s")
PY
done
