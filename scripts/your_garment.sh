#!/usr/bin/env bash
# your_garment.sh OUT [CREASE]: a garment from "another tool" and a body that is not the
# mannequin, through simulate, epnet and swingar (issue 52; docs/garments.md, "User
# garments"). Everything lands in OUT; the last lines are a table of how deep the garment's
# vertices and face centroids go into the body after the first second, how far its highest
# point (the collar) fell from the first frame to the last against the skin under it (a
# garment sliding off falls; scripts/depth_row.sh), and the pictures.
#
# - The garment: crease's long-sleeve top at about 3,000 vertices, written the way a modelling
#   tool exports a research garment: no `vt`, no `vn`, faces of bare indices.
# - The bodies: the normal mannequin, and an SMPL-family model file (scripts/smpl_style_body.py)
#   made from a heavy 1.62 m mannequin, loaded with beta 1 (10 % wider). The garment is made on
#   each (a user brings a garment modelled on their body), exported without UVs, then read back
#   by `crease garment --user --body` (checked, fitted, skinned from the body).
# - Each: simulated (Newton, the walk, 60 frames); epnet trained on it (walk, 2 cycles of 30 +
#   10 epochs) and run on the walk; swingar's tiny model, trained on a small dataset of
#   crease's own garments (not this one: swingar animates garments it has never seen), run.
# The pictures are each run's frame 45 (1.5 s), chosen before looking.
# About 12 minutes on 2 cores.
set -euo pipefail
out=${1:?usage: your_garment.sh OUT [CREASE]}
crease=${2:-$(dirname "$0")/../build/release/crease}
py=/usr/bin/python3 # Debian's, with numpy (scripts/deps.sh)
mkdir -p "$out"
frames=60 shot=45

"$crease" body --shape heavy --height 1.62 -o "$out/heavy.glb" >/dev/null
"$py" "$(dirname "$0")/smpl_style_body.py" "$out/heavy.glb" "$out/smpl_style.npz"
smpl="$out/smpl_style.npz:1"
# the garment as another tool would export it, modelled on each body; then crease's user path
for body in normal smpl; do
  if [[ $body == normal ]]; then b=normal; else b=$smpl; fi
  "$crease" garment --type longsleeve --res 3000 --body "$b" -o "$out/made_$body.obj" >/dev/null
  awk '$1 == "vt" || $1 == "vn" { next }
       $1 == "f" { for (i = 2; i <= NF; i++) { split($i, p, "/"); $i = p[1] } } { print }' \
    "$out/made_$body.obj" > "$out/exported_$body.obj"
  "$crease" garment --user "$out/exported_$body.obj" --body "$b" -o "$out/garment_$body.obj" \
    --render "$out/garment_$body.png"
done

# swingar: a tiny model on crease's own dress and skirt (2 clips, 3 bodies)
"$crease" dataset --garments dress,skirt --motions walk,twist --bodies slim,normal,heavy \
  --low-vertices 800 --frames 30 -o "$out/swingar_data" --quiet
"$crease" swingar train --dataset "$out/swingar_data" --size tiny --epochs 20 --window 4 \
  --batch 2 --lr 1e-2 -o "$out/swingar.safetensors" --quiet

for body in normal smpl; do
  g="$out/garment_$body.obj"
  if [[ $body == normal ]]; then b=normal; else b=$smpl; fi
  "$crease" simulate --garment "$g" --motion walk --body "$b" --frames $frames \
    -o "$out/sim_$body" --quiet
  "$crease" epnet train --garment "$g" --body "$b" --motions walk --frames $frames --epochs 30 \
    --pnet-epochs 10 --cycles 2 -o "$out/epnet_$body" 2> "$out/epnet_$body.log"
  "$crease" epnet run --model "$out/epnet_$body" --motion walk --frames $frames \
    -o "$out/epnet_run_$body" > /dev/null 2>&1
  "$crease" swingar run --model "$out/swingar.safetensors" --garment "$g" --body "$b" \
    --motion walk --frames $frames -o "$out/swingar_run_$body" >/dev/null
done

# depth inside the body after the first second, of vertices and face centroids; pictures
echo "| body | method | deepest vertex, mm | deepest face centroid, mm | collar drop, mm | picture (frame $shot) |"
echo "| --- | --- | --- | --- | --- | --- |"
for body in normal smpl; do
  for run in sim epnet_run swingar_run; do
    bash "$(dirname "$0")/depth_row.sh" "$crease" "$out" $run "$body" "$out/garment_$body.obj" $shot
  done
done
