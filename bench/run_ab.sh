#!/usr/bin/env bash
# A/B of two endocast binaries on the clinical table (cthead, headphantom-dicom, the 512 x 512 x 300
# phantom): RUNS alternating runs each, --threads 2; prints the medians of the report's total and
# stage timings and peak memory, wall and sys time (/usr/bin/time), the median of the per-round
# ratios of the totals (new / old, each round's two runs side by side in time), and whether the
# meshes agree.
#
#   bench/run_ab.sh OLD_BINARY NEW_BINARY [RUNS=3]      (from the repository root)
set -euo pipefail
A=$1; B=$2; RUNS=${3:-3}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DATA="$ROOT/../shared/data"
W=$(mktemp -d /tmp/endocast-ab.XXXXXX)
trap 'rm -rf "$W"' EXIT
"$B" phantom "$W/p512.nrrd" --size 512 512 300 --spacing 0.45 0.45 0.8 > /dev/null
ISO=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['suggested_iso'])" "$W/p512.json")
CASES=("p5 $W/p512.nrrd --iso $ISO")
[ -d "$DATA/cthead" ] && CASES=("ct $DATA/cthead/cthead.nhdr --iso 1300" "${CASES[@]}")
[ -d "$DATA/headphantom-dicom" ] && CASES+=("hp $DATA/headphantom-dicom --iso 250")
for i in $(seq 1 "$RUNS"); do
    for tag in a b; do
        BIN=$A; [ "$tag" = b ] && BIN=$B
        for c in "${CASES[@]}"; do
            read -ra args <<< "$c"
            n=${args[0]}
            /usr/bin/time -f "%e %M %S" -o "$W/${n}_${tag}_$i.time" "$BIN" --threads 2 extract "${args[@]:1}" \
                -o "$W/${n}_${tag}.ply" --report "$W/${n}_${tag}_$i.json" -q
        done
    done
done
python3 - "$W" "$RUNS" <<'PY'
import json, statistics as st, sys, os
w, runs = sys.argv[1], int(sys.argv[2])
for n in ['ct', 'hp', 'p5']:
    if not os.path.exists(f'{w}/{n}_a_1.json'):
        continue
    for b, name in (('a', 'old'), ('b', 'new')):
        js = [json.load(open(f'{w}/{n}_{b}_{i}.json')) for i in range(1, runs + 1)]
        tm = [open(f'{w}/{n}_{b}_{i}.time').read().split() for i in range(1, runs + 1)]
        med = lambda f: st.median(f(j) for j in js)
        stages = {k: med(lambda j: j['timings_s'][k]) for k in js[0]['timings_s'] if k != 'total'}
        print(f"{n} {name}: total {med(lambda j: j['timings_s']['total']):.2f} s, wall {st.median(float(t[0]) for t in tm):.2f} s, "
              f"sys {st.median(float(t[2]) for t in tm):.2f} s, peak {med(lambda j: j['peak_memory_mb']):.0f} MB | " +
              ' '.join(f'{k}={v:.2f}' for k, v in stages.items() if v >= 0.05))
    # The runs alternate, so each round times both binaries in the same phase of a VM whose speed
    # drifts: the median of the per-round ratios new / old is steadier than the ratio of medians.
    total = lambda b, i: json.load(open(f'{w}/{n}_{b}_{i}.json'))['timings_s']['total']
    ratios = [total('b', i) / total('a', i) for i in range(1, runs + 1)]
    print(f"{n} new/old per round: median {st.median(ratios):.3f} (" + ' '.join(f'{r:.2f}' for r in ratios) + ')')
PY
for c in "${CASES[@]}"; do
    n=${c%% *}
    cmp -s "$W/${n}_a.ply" "$W/${n}_b.ply" && echo "$n: same mesh bytes" || echo "$n: meshes differ"
done
