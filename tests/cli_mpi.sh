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
if "${mpi[@]}" "$crease" dataset --help 2>&1 | grep -q "built without MPI"; then
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

echo "cli_mpi: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
