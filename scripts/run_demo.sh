#!/usr/bin/env bash
# `make run`: the main job on built-in defaults. The drape method (paper 000)
# drapes a 1 m cloth over a ball with an implicit neural surface trained on
# physics losses until it converges (epoch 8,150; 3-4 minutes on the shared
# 2-core machine, docs/drape.md "Smooth cloth"), then renders it again from
# the side, and says where everything is.
# Usage: run_demo.sh CREASE_BINARY OUT_DIR
set -euo pipefail
crease=$1
out=$2
mkdir -p "$out"
"$crease" drape --scene ball -o "$out/drape_ball"
"$crease" render "$out/drape_ball/drape.obj" --yaw 120 --pitch 10 -o "$out/drape_ball/side.png"
"$crease" info "$out/drape_ball/drape.obj"
echo
echo "results are in $out/drape_ball/:"
echo "  drape.obj, drape.glb   the draped cloth (256 x 256 vertices, UVs), for Blender or any viewer"
echo "  drape.png              a render of the cloth over the ball"
echo "  side.png               the cloth alone, from the side, low"
echo "  sampler.png            where the adaptive sampler put its points over UV (heat map)"
echo "  loss.png, loss.jsonl   the loss terms over the epochs"
echo "  checkpoint.safetensors the trained model (add --resume to continue training from it)"
