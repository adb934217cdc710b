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
# Never part of `make check`. Set OPENBLAS_CORETYPE for this script's process
# to measure under another OpenBLAS kernel (e.g. Prescott).
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
  echo "== grid model to 1 % relative L2 (crease fit vs torch_fit.py), $threads threads"
  local t c
  rm -f "$out/nn/"*.json*
  t=$($torch_py "$peers/torch_fit.py" --device cpu --threads $threads --models grid --eval-every 5 | tail -1)
  echo "$t" >"$out/nn/torch_fit.json"
  rm -rf "$out/nn/fit_grid"
  c=$(OMP_NUM_THREADS=$threads "$crease" fit --model grid -o "$out/nn/fit_grid" --eval-every 5 \
      --quiet --json 2>"$out/nn/fit_grid.log" | tail -1)
  echo "$c" >"$out/nn/crease_fit.json"
  python3 - "$out/nn/crease_fit.json" "$out/nn/torch_fit.json" <<'PY'
import json, sys
c, t = (json.loads(open(p).read().strip().splitlines()[-1]) for p in sys.argv[1:3])
rows = [("crease", c["epochs_to_target"], c["seconds_to_target"], c["seconds"] / max(c["epochs"], 1)),
        ("pytorch", t["epochs_to_target"], t["seconds_to_target"], t["seconds_per_epoch"])]
print("%-8s %-15s %-17s %-17s" % ("peer", "epochs to 1 %", "seconds to 1 %", "seconds/epoch"))
for name, e, s, pe in rows:
    print("%-8s %-15s %-17s %-17.4f" % (name, "-" if e is None or e < 0 else e,
                                         "-" if s is None or s < 0 else "%.3f" % s, pe))
if (c["seconds_to_target"] or -1) > 0 and (t["seconds_to_target"] or -1) > 0:
    print("(PyTorch / crease seconds to 1 %%: %.2fx)" % (t["seconds_to_target"] / c["seconds_to_target"]))
PY

  echo "== MLP 6-W-W-W-3 ReLU training step, batch 4096 (bench_nn_mlp vs torch_mlp.py), $threads threads"
  OMP_NUM_THREADS=$threads "$bindir/bench_nn_mlp" 30 >"$out/nn/bench_nn_mlp.txt" ||
    { echo "bench-peers nn: bench_nn_mlp failed" >&2; return 1; }
  $torch_py "$peers/torch_mlp.py" --threads $threads --widths 64,256 >"$out/nn/torch_mlp.jsonl"
  head -2 "$out/nn/bench_nn_mlp.txt"
  printf '%-6s %-17s %-18s %-9s %-10s\n' width "crease ms/step" "pytorch ms/step" ratio "gemm share"
  local w cm tm share
  for w in 64 256; do
    cm=$(sed -n "s/^mlp 6-$w-.*step \([0-9.]*\) ms.*/\1/p" "$out/nn/bench_nn_mlp.txt")
    share=$(sed -n "s/^mlp 6-$w-.*gemm share \([0-9.]*\).*/\1/p" "$out/nn/bench_nn_mlp.txt")
    tm=$(grep "\"width\": $w," "$out/nn/torch_mlp.jsonl" | python3 -c 'import json,sys; print(json.loads(sys.stdin.read())["ms_per_step"])')
    awk -v w=$w -v c="$cm" -v t="$tm" -v s="$share" \
      'BEGIN { printf "%-6d %-17.3f %-18.3f %-9.2f %-10s\n", w, c, t, t / c, s }'
  done
  echo "(ratio = pytorch / crease: above 1 means crease is faster; outputs in $out/nn)"
}

if [[ ,$parts, == *,sim,* ]]; then sim_peers || status=1; fi
if [[ ,$parts, == *,nn,* ]]; then nn_peers || status=1; fi
exit $status
