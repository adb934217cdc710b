#!/usr/bin/env bash
# `make run`: the main job on built-in defaults. Until the first method lands
# it builds the scenes the methods drape cloth over (sphere, torus, prism,
# table box, a plane cloth), renders them and a turntable, and says where.
# Usage: run_demo.sh CREASE_BINARY OUT_DIR
set -euo pipefail
crease=$1
out=$2
mkdir -p "$out/meshes" "$out/turntable"
for kind in sphere torus prism box plane; do
  "$crease" primitive "$kind" -o "$out/meshes/$kind.obj"
  "$crease" render "$out/meshes/$kind.obj" --wire -o "$out/$kind.png"
done
"$crease" primitive torus --res 128 -o "$out/meshes/torus_fine.glb"
"$crease" render "$out/meshes/torus_fine.glb" --color-by curvature -o "$out/torus_curvature.png"
"$crease" render "$out/meshes/torus_fine.glb" --turntable 24 -o "$out/turntable/torus.png"
"$crease" info "$out/meshes/torus_fine.glb"
echo
echo "results are in $out/:"
echo "  $out/*.png               renders of the primitives (sphere, torus, prism, box, plane)"
echo "  $out/torus_curvature.png mean-curvature colour map"
echo "  $out/turntable/          24-frame turntable"
echo "  $out/meshes/             the meshes (OBJ, glb)"
