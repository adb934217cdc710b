#!/usr/bin/env bash
# cli_mpi.sh: `crease dataset` over 2 MPI ranks equals the 1-rank dataset
# byte for byte (every garment.pc2, and the manifest's sequence states), and
# a rerun under 2 ranks skips every finished sequence. Skips (77) where
# mpirun is absent or the tool was built without MPI.
# Usage: cli_mpi.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

command -v mpirun >/dev/null || { echo "cli_mpi: no mpirun, skipped"; exit 77; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
mpi=(timeout 300 mpirun --oversubscribe -np 2 -x OMP_NUM_THREADS)
if "${mpi[@]}" "$crease" dataset 2>&1 | grep -q "built without MPI"; then
  echo "cli_mpi: crease built without MPI, skipped"; exit 77
fi
args=(dataset --garments tshirt,skirt --motions walk,squat --frames 6 --low-vertices 700 --quiet)
check "1 rank" "$crease" "${args[@]}" -o "$tmp/one"
check "2 ranks" "${mpi[@]}" "$crease" "${args[@]}" -o "$tmp/two"
seqs=$(cd "$tmp/one/sequences" && ls)
check "four sequences" test "$(echo "$seqs" | wc -w)" -eq 4
for s in $seqs; do
  check "$s equal at 1 and 2 ranks" \
    cmp "$tmp/one/sequences/$s/garment.pc2" "$tmp/two/sequences/$s/garment.pc2"
done
check "manifest: four done" test "$(grep -c '"status":[[:space:]]*"done"' "$tmp/two/manifest.json")" -eq 4
check "rerun skips all" bash -c "${mpi[*]} '$crease' ${args[*]} -o '$tmp/two' --json | grep -q '\"skipped\":4,'"

# crease fit, data-parallel: 2 ranks with the same global batch end within
# 1e-5 relative of the 1-rank run (parameters, when python3 can read the
# checkpoints; the final error always)
fit=(fit --model mlp --epochs 3 --no-stop --train-res 64 --eval-res 64 --batch 512 --json)
"$crease" "${fit[@]}" -o "$tmp/fit1" 2>/dev/null | tail -n 1 > "$tmp/fit1.json"
"${mpi[@]}" "$crease" "${fit[@]}" -o "$tmp/fit2" 2>/dev/null | tail -n 1 > "$tmp/fit2.json"
rel() { grep -o '"rel_l2":[^,]*' "$1" | cut -d: -f2; }
check "fit: one report from 2 ranks" test "$(grep -c command "$tmp/fit2.json")" -eq 1
check "fit: rel_l2 within 1e-5 at 2 ranks" awk -v a="$(rel "$tmp/fit1.json")" \
  -v b="$(rel "$tmp/fit2.json")" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(a > 0 && d / a < 1e-5) }'
if command -v python3 >/dev/null; then
  check "fit: parameters within 1e-5 at 2 ranks" python3 - "$tmp/fit1/checkpoint.safetensors" \
    "$tmp/fit2/checkpoint.safetensors" <<'PY'
import json, struct, sys
def load(p):
    b = open(p, 'rb').read(); n = struct.unpack('<Q', b[:8])[0]; h = json.loads(b[8:8 + n])
    out = {}
    for k, v in h.items():
        if k == '__metadata__' or v.get('dtype') != 'F32' or k.startswith('optim'): continue
        s, e = v['data_offsets']; out[k] = struct.unpack('<%df' % ((e - s) // 4), b[8 + n + s:8 + n + e])
    return out
a, b = load(sys.argv[1]), load(sys.argv[2])
assert a and a.keys() == b.keys()
for k in a:
    scale = max(max(abs(x) for x in a[k]), 1e-12)
    err = max(abs(x - y) for x, y in zip(a[k], b[k])) / scale
    assert err < 1e-5, (k, err)
PY
fi

echo "cli_mpi: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
