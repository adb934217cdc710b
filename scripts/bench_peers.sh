#!/usr/bin/env bash
# `make bench-peers`: crease's simulator side by side with Blender's cloth
# solver on the same scene: a 1 m square cloth of (res+1)^2 vertices at y = 0.5
# dropped on a sphere of radius 0.3 m, 120 frames at 30 fps, 2 threads each,
# at res = 64 and 128 quads per side. Prints seconds per frame for Blender and
# for crease with each solver (Newton, VBD: `--solver`), the ratios (Blender /
# crease: above 1 means crease is faster) and each one's deepest vertex inside
# the sphere. The Blender harness is
# ../shared/peers/blender_drape.py (its docstring gives the scene and timing
# rules). Installs Debian's `blender` here if it is missing (root only); never
# part of `make check`.
# Usage: bench_peers.sh CREASE_BINARY [OUT_DIR]
set -euo pipefail
crease=$1
out=${2:-build/bench_peers}
root=$(cd "$(dirname "$0")/.." && pwd)
peer=${CREASE_PEERS_DIR:-$root/../shared/peers}/blender_drape.py  # CREASE_PEERS_DIR: for a worktree
frames=${PEERS_FRAMES:-120}  # PEERS_FRAMES, PEERS_RES: a shorter run
threads=2

if [[ ! -f $peer ]]; then
  echo "bench-peers: the Blender harness $peer is missing" >&2
  exit 1
fi
if ! command -v blender >/dev/null; then
  if [[ $(id -u) -ne 0 ]]; then
    echo "bench-peers: blender is not installed and installing it needs root (apt-get install blender)" >&2
    exit 1
  fi
  echo "bench-peers: installing Debian's blender (once; a few minutes)..." >&2
  if ! DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends blender >&2; then
    apt-get update >&2 || true
    if ! DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends blender >&2; then
      echo "bench-peers: could not install blender; no comparison was run" >&2
      exit 1
    fi
  fi
fi

# field FILE KEY: a top-level number from a JSON file (the last line for crease's summary)
field() {
  python3 -c 'import json,sys; t=open(sys.argv[1]).read().strip().splitlines()
try: d=json.loads("\n".join(t))
except ValueError: d=json.loads(t[-1])
print(d[sys.argv[2]])' "$1" "$2"
}

mkdir -p "$out"
printf '%-6s %-9s %-10s %-10s %-10s %-8s %-8s %-10s %-10s %-10s\n' res vertices "blender" \
  "newton" "vbd" "ratio-n" "ratio-v" "blender mm" "newton mm" "vbd mm"
for res in ${PEERS_RES:-64 128}; do
  b=$out/blender$res
  c=$out/crease$res
  mkdir -p "$b" "$c"
  blender -t $threads -b --factory-startup --python "$peer" -- --res $res --frames $frames \
    --threads $threads --collider sphere --out "$b" >"$b/log.txt" 2>&1 ||
    { echo "bench-peers: blender failed at res $res, see $b/log.txt" >&2; exit 1; }
  "$crease" primitive plane --res $((res + 1)) --size 1 -o "$c/cloth.obj" >/dev/null
  for solver in newton vbd; do
    mkdir -p "$c/$solver"
    OMP_NUM_THREADS=$threads "$crease" simulate --garment "$c/cloth.obj" --garment-offset 0,0.5,0 \
      --object sphere --frames $frames --fps 30 --material cotton --solver $solver -o "$c/$solver" \
      --quiet --json >"$c/$solver/summary.json" 2>"$c/$solver/log.txt" ||
      { echo "bench-peers: crease simulate --solver $solver failed at res $res, see $c/$solver/log.txt" >&2; exit 1; }
  done
  bs=$(field "$b/result.json" seconds_per_frame)
  ns=$(field "$c/newton/summary.json" seconds_per_frame)
  vs=$(field "$c/vbd/summary.json" seconds_per_frame)
  bp=$(field "$b/result.json" max_penetration_m)
  np=$(field "$c/newton/summary.json" max_penetration_m)
  vp=$(field "$c/vbd/summary.json" max_penetration_m)
  awk -v r=$res -v v=$(((res + 1) * (res + 1))) -v bs="$bs" -v ns="$ns" -v vs="$vs" -v bp="$bp" \
    -v np="$np" -v vp="$vp" 'BEGIN { printf "%-6d %-9d %-10.4f %-10.4f %-10.4f %-8.2f %-8.2f %-10.3f %-10.3f %-10.3f\n",
      r, v, bs, ns, vs, bs / ns, bs / vs, 1e3 * bp, 1e3 * np, 1e3 * vp }'
done
echo "(seconds per frame; ratio-n, ratio-v = blender / crease Newton, VBD; crease depth is the deepest vertex inside the"
echo " sphere before projection over the run, blender's at the last frame; outputs in $out)"
