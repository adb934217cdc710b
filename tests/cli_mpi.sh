#!/usr/bin/env bash
# cli_mpi.sh: `crease dataset` over 2 MPI ranks equals the 1-rank dataset
# byte for byte, and a rerun under 2 ranks skips every finished sequence; a
# sequence that fails on one rank leaves the others going and is recorded
# as failed; a 2-rank run killed midway and run again completes without
# redoing finished sequences and equals the 1-rank dataset (full runs only); `crease fit` at
# 2 ranks ends within 1e-5 of 1 rank. Skips (77) where mpirun is absent or
# the tool was built without MPI.
# Usage: cli_mpi.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

command -v mpirun >/dev/null || { echo "cli_mpi: no mpirun, skipped"; exit 77; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
# Under the sanitizers (make test-asan) the ranks run without leak checks:
# Open MPI keeps allocations to the end, some in plugins already unloaded
# (no suppression can name them). Memory errors are still caught.
mpi=(timeout 300 mpirun --oversubscribe -np 2 -x OMP_NUM_THREADS
  -x "ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0")
if "${mpi[@]}" "$crease" dataset 2>&1 | grep -q "built without MPI"; then
  echo "cli_mpi: crease built without MPI, skipped"; exit 77
fi
args=(dataset --garments tshirt,skirt --motions walk,squat --frames 6 --low-vertices 700 --quiet)
check "1 rank" "$crease" "${args[@]}" -o "$tmp/one"
seqs=$(cd "$tmp/one/sequences" && ls)
check "four sequences" test "$(echo "$seqs" | wc -w)" -eq 4

# same_dataset A B: the same files, the same bytes; in result.json and
# frames.jsonl the timings ("seconds...") are left out of the comparison.
same_dataset() {
  [[ "$(cd "$1" && find . -type f | sort)" == "$(cd "$2" && find . -type f | sort)" ]] || return 1
  local f strip='s/"seconds[a-z_]*":[[:space:]]*[-0-9.eE+]*//g'
  while read -r f; do
    case $f in
      *result.json | *frames.jsonl) cmp -s <(sed "$strip" "$1/$f") <(sed "$strip" "$2/$f") ;;
      *) cmp -s "$1/$f" "$2/$f" ;;
    esac || { echo "differs: $f" >&2; return 1; }
  done < <(cd "$1" && find . -type f)
}
# done_seqs DIR: the sequences whose result.json says done
done_seqs() { grep -l '"status":[[:space:]]*"done"' "$1"/sequences/*/result.json 2>/dev/null |
  xargs -r -n 1 dirname | xargs -r -n 1 basename; }
stamps() { for s in "$@"; do stat -c '%n %i %y' "$tmp/kill/sequences/$s"/{garment.pc2,result.json,frames.jsonl}; done; }

check "2 ranks" "${mpi[@]}" "$crease" "${args[@]}" -o "$tmp/two"
for s in $seqs; do
  check "$s equal at 1 and 2 ranks" \
    cmp "$tmp/one/sequences/$s/garment.pc2" "$tmp/two/sequences/$s/garment.pc2"
done
check "2 ranks: the whole dataset equals 1 rank's" same_dataset "$tmp/one" "$tmp/two"
check "manifest: four done" test "$(grep -c '"status":[[:space:]]*"done"' "$tmp/two/manifest.json")" -eq 4
check "rerun skips all" bash -c "${mpi[*]@Q} '$crease' ${args[*]} -o '$tmp/two' --json | grep -q '\"skipped\":4,'"

# A failing sequence on rank 1: sequences are dealt k mod 2 in plan order
# (tshirt walk, tshirt squat, skirt walk, skirt squat), so tshirt squat is
# rank 1's first. A plain file where its folder goes makes it fail as a full
# or broken file system would; rank 1's next sequence and rank 0's still run.
mkdir -p "$tmp/fail/sequences"
echo "not a folder" > "$tmp/fail/sequences/tshirt_low_normal_squat"
"${mpi[@]}" "$crease" "${args[@]}" -o "$tmp/fail" --json > "$tmp/fail.json" 2> "$tmp/fail.err"
check "failure: exit 1" test $? -eq 1
check "failure: 3 done, 1 failed" grep -q '"done":3,"skipped":0,"failed":1' "$tmp/fail.json"
check "failure: reported with its path" grep -q 'tshirt_low_normal_squat failed: .*tshirt_low_normal_squat' "$tmp/fail.err"
check "failure: manifest records it" python3 -c "
import json, sys
m = {q['id']: q for q in json.load(open('$tmp/fail/manifest.json'))['sequences']}
f = m['tshirt_low_normal_squat']
assert f['status'] == 'failed' and 'tshirt_low_normal_squat' in f['failure'], f
assert all(q['status'] == 'done' for k, q in m.items() if k != 'tshirt_low_normal_squat'), m"
for s in tshirt_low_normal_walk skirt_low_normal_walk skirt_low_normal_squat; do
  check "failure: $s equals 1 rank's" \
    cmp "$tmp/one/sequences/$s/garment.pc2" "$tmp/fail/sequences/$s/garment.pc2"
done
rm "$tmp/fail/sequences/tshirt_low_normal_squat"
check "failure: rerun simulates the failed one alone" bash -c \
  "${mpi[*]@Q} '$crease' ${args[*]} -o '$tmp/fail' --json | grep -q '\"done\":1,\"skipped\":3,\"failed\":0'"
check "failure: then equals 1 rank's" same_dataset "$tmp/one" "$tmp/fail"

# The kill is the same resume path as the rerun after a failure above, with a race to
# land it midway: a full run makes it, a quick one (clang, sanitizers) leaves it out.
if [[ $quick == 0 ]]; then
  # Killed midway once a first sequence is done, then the same command again. Eight sequences (four a
  # rank), so that the kill lands midway however fast the machine is (with four,
  # a quiet machine finished them all before mpirun passed the signal on).
  kargs=(dataset --garments tshirt,skirt --motions walk,squat,jump,bend --frames 6 --low-vertices 700 --quiet)
  check "1 rank, eight sequences" "$crease" "${kargs[@]}" -o "$tmp/one8"
  kseqs=$(ls "$tmp/one8/sequences")
  "${mpi[@]}" "$crease" "${kargs[@]}" -o "$tmp/kill" 2>/dev/null &
  pid=$!
  while kill -0 $pid 2>/dev/null && [[ -z "$(done_seqs "$tmp/kill")" ]]; do sleep 0.05; done
  # SIGKILL to the ranks (a crash, a lost node, a time limit's final KILL): at
  # once, where mpirun may take longer to pass SIGTERM on than the rest of the
  # run lasts; then SIGTERM to mpirun.
  pkill -KILL -f -- "dataset .* -o $tmp/kill" 2>/dev/null
  kill -TERM $pid 2>/dev/null
  wait $pid
  finished=$(done_seqs "$tmp/kill")
  nfin=$(echo "$finished" | wc -w)
  check "kill: came midway (1 to 7 of 8 done: $nfin)" test "$nfin" -ge 1 -a "$nfin" -le 7
  before=$(stamps $finished)
  # A kill while a file is renamed into place leaves its temporary: one planted
  # in an unfinished sequence's folder must be gone after the rerun.
  for s in $kseqs; do
    grep -qx "$s" <<<"$finished" && continue
    mkdir -p "$tmp/kill/sequences/$s" && echo partial > "$tmp/kill/sequences/$s/garment.pc2.tmp.99999"
    break
  done
  "${mpi[@]}" "$crease" "${kargs[@]}" -o "$tmp/kill" --json > "$tmp/kill.json" 2>/dev/null
  check "kill: rerun succeeds" test $? -eq 0
  check "kill: rerun skips the $nfin finished" grep -q "\"done\":$((8 - nfin)),\"skipped\":$nfin,\"failed\":0" "$tmp/kill.json" || { cat "$tmp/kill.json" >&2; ls -l "$tmp"/kill/sequences/* >&2; }
  check "kill: finished sequences untouched (inode, mtime)" test "$before" == "$(stamps $finished)"
  check "kill: then equals 1 rank's" same_dataset "$tmp/one8" "$tmp/kill"
fi

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
