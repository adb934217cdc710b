#!/usr/bin/env bash
# `make bench-peers`: crease side by side with its peers, one run, 2 threads
# each. Two parts (the third argument picks them; default both):
#   sim  crease's simulator and Blender's cloth solver on the same scene: a
#        1 m square cloth of (res+1)^2 vertices at y = 0.5 dropped on a sphere
#        of radius 0.3 m, 120 frames at 30 fps, at res = 64 and 128 quads per
#        side. Prints seconds per frame for Blender and for crease with each
#        solver (Newton, VBD: `--solver`; and VBD with its coarse correction,
#        PEERS_VBD_COARSE, default "--vbd-coarse 2 --vbd-coarse-refresh 3"),
#        the ratios (Blender / crease: above
#        1 means crease is faster) and each one's deepest vertex inside the
#        sphere. PEERS_FRAMES, PEERS_RES: a shorter run. The harness is
#        ../shared/peers/blender_drape.py (its docstring gives the scene and
#        timing rules). Installs Debian's `blender` if it is missing (root).
#   nn   the neural engine and PyTorch 1.13 on the CPU: `crease fit --model
#        grid` against ../shared/peers/torch_fit.py (the same model, data and
#        batches, to 1 % relative L2, evaluated every 5 epochs), and
#        bench_nn_mlp against ../shared/peers/torch_mlp.py (the 6-W-W-W-3 ReLU
#        training step at batch 4,096, W = 64 and 256). Installs Debian's
#        `python3-torch` if it is missing (root), here only.
#        Each comparison runs PEERS_REPEAT times (default 3), the two programs
#        alternating, and the median ratio is printed: on a shared 2-core
#        virtual machine one run's time moves by up to 2x with the neighbours.
#        PyTorch runs on the OpenBLAS kernel OpenBLAS picks itself (the
#        OPENBLAS_CORETYPE / OPENBLAS_L2_SIZE that some machines set are dropped
#        for its process; PEERS_TORCH_OPENBLAS=env keeps them); the kernel each
#        program ran is printed.
# Never part of `make check`. Set OPENBLAS_CORETYPE for this script's process
# to measure crease under another OpenBLAS kernel (e.g. Prescott).
# BENCH_THREADS (default 2) sets the threads of every run.
# Usage: bench_peers.sh CREASE_BINARY [OUT_DIR] [sim,nn]
set -euo pipefail
crease=$1
out=${2:-build/bench_peers}
parts=${3:-sim,nn}
root=$(cd "$(dirname "$0")/.." && pwd)
# the peers sit in ../shared/peers of the main checkout (two levels up from a worktree
# under wt/); CREASE_PEERS overrides
peers=${CREASE_PEERS:-$root/../shared/peers}
[[ -d $peers || -n ${CREASE_PEERS:-} ]] || peers=$root/../../shared/peers
peer=$peers/blender_drape.py
bindir=$(cd "$(dirname "$crease")" && pwd)
frames=${PEERS_FRAMES:-120}
threads=${BENCH_THREADS:-2}
status=0

# field FILE KEY: a top-level number from a JSON file (the last line for crease's summary)
field() {
  python3 -c 'import json,sys; t=open(sys.argv[1]).read().strip().splitlines()
try: d=json.loads("\n".join(t))
except ValueError: d=json.loads(t[-1])
print(d[sys.argv[2]])' "$1" "$2"
}

# strain REST RESULT [options]: the p99 edge strain of RESULT's last frame (its JSON beside
# RESULT), so that a fast result that is stretched or crumpled does not pass for a good one.
strain() {
  python3 "$root/scripts/edge_strain.py" "$@" >"$2.strain.json" && field "$2.strain.json" p99
}

sim_peers() {
  if [[ ! -f $peer ]]; then
    echo "bench-peers: the Blender harness $peer is missing" >&2
    return 1
  fi
  if ! command -v blender >/dev/null; then
    if [[ $(id -u) -ne 0 ]]; then
      echo "bench-peers: blender is not installed and installing it needs root (apt-get install blender)" >&2
      return 1
    fi
    echo "bench-peers: installing Debian's blender (once; a few minutes)..." >&2
    if ! DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends blender >&2; then
      apt-get update >&2 || true
      if ! DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends blender >&2; then
        echo "bench-peers: could not install blender; no comparison was run" >&2
        return 1
      fi
    fi
  fi

  mkdir -p "$out"
  coarse_args=${PEERS_VBD_COARSE:---vbd-coarse 2 --vbd-coarse-refresh 3}
  printf '%-6s %-9s %-8s %-8s %-8s %-8s %-8s %-8s %-8s %-22s %-26s\n' res vertices "blender" \
    "newton" "vbd" "vbd+c" "ratio-n" "ratio-v" "ratio-vc" "depth mm b/n/v/vc" "strain p99 % b/n/v/vc"
  for res in ${PEERS_RES:-64 128}; do
    b=$out/blender$res
    c=$out/crease$res
    mkdir -p "$b" "$c"
    blender -t $threads -b --factory-startup --python "$peer" -- --res $res --frames $frames \
      --threads $threads --collider sphere --out "$b" >"$b/log.txt" 2>&1 ||
      { echo "bench-peers: blender failed at res $res, see $b/log.txt" >&2; return 1; }
    "$crease" primitive plane --res $((res + 1)) --size 1 -o "$c/cloth.obj" >/dev/null
    for run in newton vbd vbdc; do
      solver=${run%c}
      extra=()
      [[ $run == vbdc ]] && read -r -a extra <<<"$coarse_args"
      mkdir -p "$c/$run"
      OMP_NUM_THREADS=$threads "$crease" simulate --garment "$c/cloth.obj" --garment-offset 0,0.5,0 \
        --object sphere --frames $frames --fps 30 --material cotton --solver $solver "${extra[@]}" \
        -o "$c/$run" --quiet --json >"$c/$run/summary.json" 2>"$c/$run/log.txt" ||
        { echo "bench-peers: crease simulate --solver $solver ${extra[*]} failed at res $res, see $c/$run/log.txt" >&2; return 1; }
    done
    bs=$(field "$b/result.json" seconds_per_frame)
    ns=$(field "$c/newton/summary.json" seconds_per_frame)
    vs=$(field "$c/vbd/summary.json" seconds_per_frame)
    cs=$(field "$c/vbdc/summary.json" seconds_per_frame)
    cp=$(field "$c/vbdc/summary.json" max_penetration_m)
    cst=$(strain "$c/cloth.obj" "$c/vbdc/sim.pc2")
    bp=$(field "$b/result.json" max_penetration_m)
    np=$(field "$c/newton/summary.json" max_penetration_m)
    vp=$(field "$c/vbd/summary.json" max_penetration_m)
    # Blender's rest edges are its grid's, 1 m / res.
    bst=$(strain "$b/final.obj" "$b/final.obj" \
      --rest-length "$(awk -v r=$res 'BEGIN { print 1.0 / r }')")
    nst=$(strain "$c/cloth.obj" "$c/newton/sim.pc2")
    vst=$(strain "$c/cloth.obj" "$c/vbd/sim.pc2")
    awk -v r=$res -v v=$(((res + 1) * (res + 1))) -v bs="$bs" -v ns="$ns" -v vs="$vs" -v cs="$cs" \
      -v bp="$bp" -v np="$np" -v vp="$vp" -v cp="$cp" -v bst="$bst" -v nst="$nst" -v vst="$vst" \
      -v cst="$cst" \
      'BEGIN { printf "%-6d %-9d %-8.4f %-8.4f %-8.4f %-8.4f %-8.2f %-8.2f %-8.2f %-22s %.2f/%.2f/%.2f/%.2f\n",
        r, v, bs, ns, vs, cs, bs / ns, bs / vs, bs / cs,
        sprintf("%.2f/%.2f/%.2f/%.2f", 1e3 * bp, 1e3 * np, 1e3 * vp, 1e3 * cp),
        1e2 * bst, 1e2 * nst, 1e2 * vst, 1e2 * cst }'
  done
  echo "(seconds per frame; ratio-n, ratio-v, ratio-vc = blender / crease Newton, VBD, VBD + coarse ($coarse_args);"
  echo " crease depth is the deepest vertex inside the"
  echo " sphere before projection over the run, blender's at the last frame; strain p99: the 99th percentile of"
  echo " |l / l0 - 1| over the edges at the last frame, scripts/edge_strain.py; outputs in $out)"
}

# pyval JSON_LINE KEY: one field of a JSON line ("null" stays null)
pyval() {
  python3 -c 'import json,sys; v=json.loads(sys.argv[1]).get(sys.argv[2]); print("null" if v is None else v)' "$1" "$2"
}

nn_peers() {
  local torch_py=/usr/bin/python3
  if ! $torch_py -c 'import torch' 2>/dev/null; then
    if [[ $(id -u) -ne 0 ]]; then
      echo "bench-peers nn: python3-torch is not installed and installing it needs root" >&2
      return 1
    fi
    echo "bench-peers nn: installing Debian's python3-torch (once; a few minutes)..." >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y python3-torch >&2 ||
      { apt-get update >&2 || true; DEBIAN_FRONTEND=noninteractive apt-get install -y python3-torch >&2; } ||
      { echo "bench-peers nn: could not install python3-torch; no comparison was run" >&2; return 1; }
  fi
  mkdir -p "$out/nn"
  # PyTorch runs on OpenBLAS's own choice of kernel (its best on this CPU): the variables some
  # machines set to pin an old kernel are dropped for its process only. crease runs in the
  # environment as given; its GEMM does not depend on OpenBLAS's kernel (docs/nn.md).
  local -a torch_env=(env)
  [[ ${PEERS_TORCH_OPENBLAS:-own} == env ]] || torch_env=(env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE)
  local kernel_py='import ctypes, torch
lib = next((l.split()[-1] for l in open("/proc/self/maps") if "blas" in l.split()[-1]), None)
try:
    f = ctypes.CDLL(lib).openblas_get_corename; f.restype = ctypes.c_char_p; print(f().decode())
except Exception:
    print("unknown (%s)" % lib)'
  echo "OpenBLAS kernel: crease's process $(OMP_NUM_THREADS=1 "$bindir/bench_nn_mlp" 1 2>/dev/null |
    sed -n 's/.*core type \([A-Za-z0-9]*\).*/\1/p' | head -1), PyTorch's $("${torch_env[@]}" $torch_py -c "$kernel_py")"
  local reps=${PEERS_REPEAT:-3} rep t c
  echo "== grid model to 1 % relative L2 (crease fit vs torch_fit.py), $threads threads, $reps runs each, alternating"
  rm -f "$out/nn/"*.json*
  for rep in $(seq "$reps"); do
    t=$("${torch_env[@]}" $torch_py "$peers/torch_fit.py" --device cpu --threads $threads --models grid \
        --eval-every 5 | tail -1)
    echo "$t" >>"$out/nn/torch_fit.jsonl"
    rm -rf "$out/nn/fit_grid"
    c=$(OMP_NUM_THREADS=$threads "$crease" fit --model grid -o "$out/nn/fit_grid" --eval-every 5 \
        --quiet --json 2>"$out/nn/fit_grid.log" | tail -1)
    echo "$c" >>"$out/nn/crease_fit.jsonl"
  done
  python3 - "$out/nn/crease_fit.jsonl" "$out/nn/torch_fit.jsonl" <<'PY'
import json, statistics, sys
cs, ts = ([json.loads(l) for l in open(p) if l.strip()] for p in sys.argv[1:3])
print("%-4s %-22s %-22s %s" % ("run", "crease epochs / s", "pytorch epochs / s", "pytorch / crease"))
ratios = []
for i, (c, t) in enumerate(zip(cs, ts), 1):
    ok = (c["seconds_to_target"] or -1) > 0 and (t["seconds_to_target"] or -1) > 0
    r = t["seconds_to_target"] / c["seconds_to_target"] if ok else None
    if r: ratios.append(r)
    print("%-4d %-22s %-22s %s" % (i, "%s / %.3f" % (c["epochs_to_target"], c["seconds_to_target"]),
                                   "%s / %.3f" % (t["epochs_to_target"], t["seconds_to_target"] or -1),
                                   "%.2fx" % r if r else "-"))
if ratios:
    print("(PyTorch / crease seconds to 1 %%, median of %d: %.2fx)" % (len(ratios), statistics.median(ratios)))
PY

  echo "== MLP 6-W-W-W-3 ReLU training step, batch 4096 (bench_nn_mlp vs torch_mlp.py), $threads threads, $reps runs each, alternating"
  rm -f "$out/nn/bench_nn_mlp.txt" "$out/nn/torch_mlp.jsonl"
  for rep in $(seq "$reps"); do
    OMP_NUM_THREADS=$threads "$bindir/bench_nn_mlp" 30 >>"$out/nn/bench_nn_mlp.txt" ||
      { echo "bench-peers nn: bench_nn_mlp failed" >&2; return 1; }
    "${torch_env[@]}" $torch_py "$peers/torch_mlp.py" --threads $threads --widths 64,256 \
      >>"$out/nn/torch_mlp.jsonl"
  done
  head -2 "$out/nn/bench_nn_mlp.txt"
  grep "step alone" "$out/nn/bench_nn_mlp.txt" | sed 's/^ */crease, /'
  python3 - "$out/nn/bench_nn_mlp.txt" "$out/nn/torch_mlp.jsonl" <<'PY'
import json, re, statistics, sys
crease = {}
for line in open(sys.argv[1]):
    m = re.match(r"mlp 6-(\d+)-.*step ([0-9.]+) ms.*gemm share ([0-9.]+)", line)
    if m: crease.setdefault(int(m[1]), []).append((float(m[2]), float(m[3])))
torch = {}
for line in open(sys.argv[2]):
    if line.strip():
        d = json.loads(line); torch.setdefault(d["width"], []).append(d["ms_per_step"])
print("%-6s %-4s %-15s %-16s %-8s %s" % ("width", "run", "crease ms/step", "pytorch ms/step", "ratio", "gemm share"))
for w in sorted(crease):
    ratios = []
    for i, ((cm, share), tm) in enumerate(zip(crease[w], torch.get(w, [])), 1):
        ratios.append(tm / cm)
        print("%-6d %-4d %-15.3f %-16.3f %-8.2f %.2f" % (w, i, cm, tm, tm / cm, share))
    if ratios:
        print("%-6d median ratio %.2fx, median gemm share %.2f" % (w, statistics.median(ratios),
              statistics.median(s for _, s in crease[w])))
PY
  echo "(ratio = pytorch / crease: above 1 means crease is faster; outputs in $out/nn)"
}

if [[ ,$parts, == *,sim,* ]]; then sim_peers || status=1; fi
if [[ ,$parts, == *,nn,* ]]; then nn_peers || status=1; fi
exit $status
