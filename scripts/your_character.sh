#!/usr/bin/env bash
# your_character.sh OUT [CREASE]: a rigged glTF character that is not the mannequin, driven by
# its own animation and by a CMU-layout BVH, with a garment modelled on it, through simulate,
# epnet and swingar (issue 52; docs/body.md, "A character as the body"). Everything lands in
# OUT; the last lines are a table of how deep the garment's vertices and face centroids go into
# the character after the first second, how far its highest point (the collar) fell from the
# first frame to the last against the skin under it (a garment sliding off falls;
# scripts/depth_row.sh), and the pictures.
#
# - The character (tests/make_character.py): crease's mannequin dancing (`pose-body --clip
#   dance`), made into what another tool would write: Mixamo's joint names, legs x1.12, spine
#   x1.15, arms x0.9 (1.87 m), a T-pose rest, a root joint on the floor and end joints past the
#   head and toes that no body has, all under a Blender-style "Armature" node (Z-up,
#   centimetres, scale 0.01); the dance kept as the file's own animation.
# - The motions: the file's own animation (`--motion char.glb`) and examples/cmu_walk_bvh.c's
#   CMU-layout walk (120 fps, a T-pose frame 0, CMU's joint names and units).
# - The garment: crease's t-shirt at about 2,000 vertices modelled on the character's rest.
# - Each motion: simulated (Newton, 60 frames); epnet trained on the character (walk and
#   dance clips, 2 cycles of 30 + 10 epochs) and run; swingar's tiny model, trained on a small
#   dataset of crease's own garments on the mannequins (neither this garment nor this body), run.
# The pictures are each run's frame 45 (1.5 s), chosen before looking.
# About 10 minutes on 2 cores.
set -euo pipefail
out=${1:?usage: your_character.sh OUT [CREASE]}
crease=${2:-$(dirname "$0")/../build/release/crease}
bin=$(dirname "$crease")
py=/usr/bin/python3 # Debian's, with numpy (scripts/deps.sh)
mkdir -p "$out"
frames=60 shot=45

"$crease" pose-body --clip dance --frames 120 -o "$out/dance.glb" >/dev/null
"$py" "$(dirname "$0")/../tests/make_character.py" "$out/dance.glb" "$out/char.glb" mixamo \
  proportions tpose animated extra armature
"$bin/example_cmu_walk_bvh" "$out/cmu_walk.bvh" 4 >/dev/null
c="$out/char.glb"
"$crease" garment --type tshirt --res 2000 --body "$c" -o "$out/tshirt.obj" \
  --render "$out/tshirt.png" 2> "$out/garment.log"
g="$out/tshirt.obj"

"$crease" dataset --garments dress,skirt --motions walk,twist --bodies slim,normal,heavy \
  --low-vertices 800 --frames 30 -o "$out/swingar_data" --quiet
"$crease" swingar train --dataset "$out/swingar_data" --size tiny --epochs 20 --window 4 \
  --batch 2 --lr 1e-2 -o "$out/swingar.safetensors" --quiet
"$crease" epnet train --garment "$g" --body "$c" --motions walk,dance --frames $frames \
  --epochs 30 --pnet-epochs 10 --cycles 2 -o "$out/epnet" 2> "$out/epnet.log"

for motion in own cmu; do
  m="$c"
  [[ $motion == cmu ]] && m="$out/cmu_walk.bvh"
  "$crease" simulate --garment "$g" --motion "$m" --body "$c" --frames $frames \
    -o "$out/sim_$motion" --quiet
  "$crease" epnet run --model "$out/epnet" --motion "$m" --frames $frames \
    -o "$out/epnet_run_$motion" > /dev/null 2>&1
  "$crease" swingar run --model "$out/swingar.safetensors" --garment "$g" --body "$c" \
    --motion "$m" --frames $frames -o "$out/swingar_run_$motion" >/dev/null
done

# depth inside the body after the first second, of vertices and face centroids; pictures
echo "| motion | method | deepest vertex, mm | deepest face centroid, mm | collar drop, mm | picture (frame $shot) |"
echo "| --- | --- | --- | --- | --- | --- |"
for motion in own cmu; do
  for run in sim epnet_run swingar_run; do
    bash "$(dirname "$0")/depth_row.sh" "$crease" "$out" $run "$motion" "$g" $shot
  done
done
