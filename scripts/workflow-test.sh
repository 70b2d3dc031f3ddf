#!/usr/bin/env bash
# CI check of workflow/Snakefile: two small phantoms, `snakemake --cores 2`, then summary.csv must
# have the batch's header and two rows with status ok.
# Usage: scripts/workflow-test.sh [ENDOCAST_BINARY]   (default build/bin/endocast)
# Exit status 77 (ctest SKIP_RETURN_CODE) when snakemake is not installed.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BIN=$(realpath "${1:-build/bin/endocast}")

if ! command -v snakemake >/dev/null 2>&1; then
  echo "workflow-test: SKIPPED: snakemake is not installed (apt-get install snakemake)"
  exit 77
fi
[ -x "$BIN" ] || { echo "workflow-test: $BIN: no endocast binary (build first)"; exit 1; }
echo "workflow-test: snakemake $(snakemake --version)"

WORK=$(mktemp -d "${TMPDIR:-/tmp}/endocast-workflow.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
for seed in 1 2; do
  "$BIN" phantom "$WORK/skull$seed.nrrd" --preset human --spacing 2 2 2 --seed "$seed" >/dev/null
done
cat > "$WORK/config.yaml" <<YAML
endocast: $BIN
outdir: $WORK/results
threads: 1
extract_options: ["--seed-mode", "auto"]
specimens:
  skull1:
    input: $WORK/skull1.nrrd
  skull2:
    input: $WORK/skull2.nrrd
YAML

snakemake -s "$ROOT/workflow/Snakefile" --cores 2 --configfile "$WORK/config.yaml" \
  --directory "$WORK" --quiet

SUMMARY="$WORK/results/summary.csv"
HEADER="specimen,input,isovalue,ecv_ml,surface_area_mm2,faces,closed_manifold,seconds,status,error,bone_contact"
[ "$(head -1 "$SUMMARY")" = "$HEADER" ] || { echo "workflow-test: FAILED: bad header"; cat "$SUMMARY"; exit 1; }
ok=$(tail -n +2 "$SUMMARY" | awk -F, '$9 == "ok"' | wc -l)
rows=$(tail -n +2 "$SUMMARY" | wc -l)
cat "$SUMMARY"
for s in skull1 skull2; do
  for f in endocast.stl report.json log.txt status.json; do
    [ -s "$WORK/results/$s/$f" ] || { echo "workflow-test: FAILED: no $s/$f"; exit 1; }
  done
done
if [ "$rows" -ne 2 ] || [ "$ok" -ne 2 ]; then
  echo "workflow-test: FAILED: expected 2 rows with status ok, got $rows rows, $ok ok"
  exit 1
fi
echo "workflow-test: OK (2 specimens)"
