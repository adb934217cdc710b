#!/usr/bin/env bash
# bench_mpi.sh: crease's two jobs over MPI ranks, in one run (docs/mpi.md):
#   dataset generation, sequences per minute (whole command: assets, plan,
#   sequences, manifest), and `crease fit` training, points per second
#   (training time only, the all-reduce included), at 1 rank (no launcher)
#   and at each rank count of BENCH_MPI_RANKS under mpirun; then the expected
#   scaling to 16 and 64 ranks from the measured 1-rank compute per step, the
#   all-reduce's bytes per step and a 10 Gb/s link (the model in docs/mpi.md).
# Each rank runs one thread (OMP_NUM_THREADS=1, OpenBLAS on one thread);
# OpenBLAS names the kernel it loaded in every process (OPENBLAS_VERBOSE=2).
# Figures are medians of BENCH_MPI_REPEAT runs (fit) and
# BENCH_MPI_DATASET_REPEAT runs (dataset), the rank counts interleaved so
# that each meets the same load on a shared machine; ranks are not bound to
# cores (--bind-to none: on a loaded machine a bound rank waits for its core),
# a waiting rank yields its core (mpi_yield_when_idle), and each process has
# a session of its own (setsid): with the kernel's autogroup scheduling
# (/proc/sys/kernel/sched_autogroup_enabled) a loaded machine shares its CPU
# per session, so ranks in one session would split one share between them
# and no rank count could run faster than one.
# Usage: bench/bench_mpi.sh [PATH_TO_CREASE] (default build/release/crease)
set -eu
crease=$(realpath "${1:-build/release/crease}")
ranks=${BENCH_MPI_RANKS:-2}
repeat=${BENCH_MPI_REPEAT:-3}
drepeat=${BENCH_MPI_DATASET_REPEAT:-1}
link_Bps=1.25e9 # 10 Gb/s
command -v mpirun >/dev/null || { echo "bench_mpi: no mpirun" >&2; exit 1; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1 \
  OPENBLAS_NUM_THREADS=1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

dargs=(dataset --garments tshirt,skirt --motions walk,squat,bend --frames 8 --low-vertices 800
  --quiet --json)
fargs=(fit --model mlp --epochs 5 --no-stop --train-res 128 --eval-res 64 --eval-every 5
  --checkpoint-every 0 --batch 4096 --quiet --json)
points=$((5 * 128 * 128)) steps=$((5 * 128 * 128 / 4096))

launch() { # launch N CMD...: CMD on N ranks (1: no launcher)
  local n=$1; shift
  if [[ $n -eq 1 ]]; then setsid -w "$@"; else
    mpirun --oversubscribe --bind-to none --mca mpi_yield_when_idle 1 -np "$n" \
      -x OMP_NUM_THREADS -x OPENBLAS_NUM_THREADS -x OPENBLAS_VERBOSE setsid -w "$@"
  fi
}
now() { date +%s.%N; }
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
key() { grep -o "\"$1\":[-0-9.eE+]*" | head -n 1 | cut -d: -f2; }

echo "bench_mpi: $(nproc --all) cores, load $(cut -d' ' -f1-3 /proc/loadavg), $(mpirun --version | head -n 1)"
echo "dataset: crease ${dargs[*]}"
echo "fit:     crease ${fargs[*]} ($points points, $steps steps)"
printf '\n| ranks | dataset s | sequences/min | sum of sequence s | fit s | points/s | OpenBLAS core |\n'
printf '| --- | --- | --- | --- | --- | --- | --- |\n'
for i in $(seq "$repeat"); do
  for n in 1 $ranks; do
    if [[ $i -le $drepeat ]]; then
      rm -rf "$tmp/ds$n"
      t0=$(now)
      launch "$n" "$crease" "${dargs[@]}" -o "$tmp/ds$n" > "$tmp/ds$n.json" 2>/dev/null
      echo "$(now) - $t0" | bc -l >> "$tmp/dwall$n"
      cat "$tmp/ds$n"/sequences/*/result.json | grep -o '"seconds":[[:space:]]*[0-9.eE+-]*' |
        awk -F: '{ s += $2 } END { printf "%.2f\n", s }' >> "$tmp/dseq$n"
    fi
    rm -rf "$tmp/fit"
    OPENBLAS_VERBOSE=2 launch "$n" "$crease" "${fargs[@]}" -o "$tmp/fit" > "$tmp/fit$n.json" \
      2> "$tmp/fit$n.err"
    tail -n 1 "$tmp/fit$n.json" | key seconds >> "$tmp/fsec$n"
  done
done
for n in 1 $ranks; do
  dwall=$(median < "$tmp/dwall$n") seqsum=$(median < "$tmp/dseq$n") fsec=$(median < "$tmp/fsec$n")
  nseq=$(key sequences < "$tmp/ds$n.json")
  params=$(tail -n 1 "$tmp/fit$n.json" | key params)
  core=$(grep -o 'Core: [A-Za-z0-9_]*' "$tmp/fit$n.err" | sort | uniq -c |
    awk '{ printf "%s%s x%d", (NR > 1 ? ", " : ""), $3, $1 }')
  awk -v n="$n" -v w="$dwall" -v s="$nseq" -v q="$seqsum" -v f="$fsec" -v p="$points" -v c="$core" \
    'BEGIN { printf "| %d | %.2f | %.1f | %s | %.3f | %.0f | %s |\n", n, w, 60 * s / w, q, f, p / f, c }'
  [[ $n -eq 1 ]] && { dwall1=$dwall seqsum1=$seqsum nseq1=$nseq fsec1=$fsec; }
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"

# The model (docs/mpi.md): a step's compute splits evenly over the ranks; the
# fixed-order all-reduce gathers every rank's gradient on rank 0 and
# broadcasts the sum (binomial tree), so a step moves (N - 1 + ceil(log2 N))
# x 4 P bytes through rank 0's link. A dataset's sequences are independent:
# T(N) = assets + ceil(S / N) x (seconds per sequence), assets made on every
# rank at once.
echo
awk -v p="$params" -v f="$fsec1" -v st="$steps" -v bw="$link_Bps" -v w="$dwall1" -v q="$seqsum1" \
  -v s="$nseq1" 'BEGIN {
  bytes = 4 * p; tc = f / st; ts = q / s; ta = w - q;
  printf "fit: %d parameters, %.0f bytes all-reduced a step; 1-rank compute %.2f ms a step (batch 4096)\n", p, bytes, 1e3 * tc;
  printf "dataset: %.2f s a sequence, %.2f s of assets and the rest (1 rank)\n\n", ts, ta;
  printf "| ranks | fit compute ms/step | all-reduce ms/step at 10 Gb/s | fit speed-up | dataset of 60 sequences: s | sequences/min |\n";
  printf "| --- | --- | --- | --- | --- | --- |\n";
  split("1 2 16 64", ns, " ");
  for (i = 1; i <= 4; i++) {
    n = ns[i]; lg = 0; while (2 ^ lg < n) lg++;
    comm = n > 1 ? (n - 1 + lg) * bytes / bw : 0;
    per = tc / n + comm;
    dt = ta + int((60 + n - 1) / n) * ts;
    printf "| %d | %.3f | %.3f | %.1f | %.1f | %.0f |\n", n, 1e3 * tc / n, 1e3 * comm, tc / per, dt, 3600 / dt;
  }
}'
