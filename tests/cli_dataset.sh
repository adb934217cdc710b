#!/usr/bin/env bash
# cli_dataset.sh: `crease dataset` end to end on a tiny dataset (one garment,
# one motion, 4 frames): the summary, the layout, resuming, exit codes
# (0 ok, 1 bad input naming what was wrong, 2 usage).
# Usage: cli_dataset.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

check "dataset --help" bash -c "'$crease' dataset --help | grep -q usage"
check "dataset" bash -c "'$crease' dataset --garments tshirt --motions walk --low-vertices 600 \
  --frames 4 -o '$tmp/data' --quiet --json > '$tmp/d.json'"
check "dataset fields" json_has "$tmp/d.json" command sequences done skipped failed max_inside_share \
  max_inside_share_solver
check "dataset one done" grep -q '"done":1,' "$tmp/d.json"
check "dataset layout" test -s "$tmp/data/manifest.json" -a -s "$tmp/data/bodies/normal/rest.obj" \
  -a -s "$tmp/data/bodies/normal/walk.pc2" -a -s "$tmp/data/motions/walk.npz" \
  -a -s "$tmp/data/garments/normal/tshirt_low.obj" \
  -a -s "$tmp/data/sequences/tshirt_low_normal_walk/garment.pc2" \
  -a -s "$tmp/data/sequences/tshirt_low_normal_walk/result.json"
check "dataset resumes" bash -c "'$crease' dataset --garments tshirt --motions walk \
  --low-vertices 600 --frames 4 -o '$tmp/data' --quiet --json | grep -q '\"skipped\":1,'"
# a twin dataset: the same def re-run from a start moved 0.1 mm, recorded in the manifest
check "dataset --twin" bash -c "'$crease' dataset --garments tshirt --motions walk --low-vertices 600 \
  --frames 4 --twin -o '$tmp/twin' --quiet --json | grep -q '\"twin\":{\"offset_m\":\[0,0,0.0001\]'"
check "twin: the manifest says so, the start moved 0.1 mm" python3 -c "
import json, struct
m = json.load(open('$tmp/twin/manifest.json'))
assert m['def']['twin'] == {'offset_m': [0, 0, 0.0001], 'friction_delta': 0}, m['def']
assert 'twin' not in json.load(open('$tmp/data/manifest.json'))['def']
s = 'sequences/tshirt_low_normal_walk/garment.pc2'
a = open('$tmp/data/' + s, 'rb').read()[32:]; b = open('$tmp/twin/' + s, 'rb').read()[32:]
n = len(a) // 4
a = struct.unpack('<%df' % n, a); b = struct.unpack('<%df' % n, b)
v = n // 5 // 3   # five samples: check the first
assert max(abs(b[i] - a[i] - (1e-4 if i % 3 == 2 else 0)) for i in range(3 * v)) < 1e-6
"
# garment variants: a spec and --garment-variants, named by their labels, specs in the manifest
check "dataset variants" "$crease" dataset --garments skirt:flare=25 --garment-variants 2 --seed 4 \
  --motions walk --low-vertices 800 --frames 1 -o "$tmp/datav" --quiet
check "variant files" test -s "$tmp/datav/garments/normal/skirt_flare25_seed4_low.obj" \
  -a -s "$tmp/datav/sequences/skirt_flare25_seed5_low_normal_walk/garment.pc2"
check "variant spec" grep -Eq '"spec":[[:space:]]*"skirt:length=[0-9.]+:flare=25:' \
  "$tmp/datav/manifest.json"
expect_exit 1 "flare = 99" dataset --garments skirt:flare=99 --motions walk -o "$tmp/datab" --quiet
# a motion file at 60 fps: resampled to the dataset's 30, eased in from the rest pose
"$crease" motion --clip walk --frames 13 --fps 60 -o "$tmp/walk60.npz" >/dev/null 2>&1
check "dataset on a file" "$crease" dataset --garments tshirt --motions "$tmp/walk60.npz" \
  --low-vertices 600 --frames 2 -o "$tmp/data60" --quiet
m60="$tmp/data60/manifest.json"
check "manifest source rate" grep -Eq '"source_fps":[[:space:]]*60' "$m60"
check "manifest used rate" grep -Eq '"fps":[[:space:]]*30,' "$m60"
# 13 frames at 60 fps are 7 at 30, after the 1 s ease-in's 30
check "manifest frames" grep -Eq '"frames":[[:space:]]*37,' "$m60"
check "manifest ease-in" grep -Eq '"ease_in_frames":[[:space:]]*30' "$m60"
# two motions with one label (a clip and a file, two files) are refused before any work
mkdir -p "$tmp/m2" && cp "$tmp/walk60.npz" "$tmp/walk.npz" && cp "$tmp/walk60.npz" "$tmp/m2/"
expect_exit 1 "motions 'walk' and '.*/walk.npz' have the same label 'walk'.*rename one" dataset \
  --garments tshirt --motions "walk,$tmp/walk.npz" --frames 2 -o "$tmp/dup" --quiet
expect_exit 1 "walk60.npz' and '.*m2/walk60.npz' have the same label 'walk60'" dataset \
  --garments tshirt --motions "$tmp/walk60.npz,$tmp/m2/walk60.npz" --frames 2 -o "$tmp/dup" --quiet
check "nothing written for clashing labels" test ! -e "$tmp/dup"
seq="$tmp/data/sequences/tshirt_low_normal_walk/garment.pc2"
check "render a frame, garment on body" "$crease" render \
  "$tmp/data/garments/normal/tshirt_low.obj" --pc2 "$seq" \
  "$tmp/data/bodies/normal/rest.obj" --pc2 "$tmp/data/bodies/normal/walk.pc2" \
  --frame 3 --size 64 -o "$tmp/frame3.png"
check "render frame png" bash -c "head -c 4 '$tmp/frame3.png' | grep -q PNG"
expect_exit 1 "no frame 9" render "$tmp/data/garments/normal/tshirt_low.obj" --pc2 "$seq" \
  --frame 9 -o "$tmp/bad.png"
expect_exit 1 "vertices" render "$tmp/data/bodies/normal/rest.obj" --pc2 "$seq" -o "$tmp/bad.png"
expect_exit 2 "must follow its mesh" render --pc2 "$seq" -o "$tmp/bad.png"
expect_exit 1 "poncho" dataset --garments poncho --motions walk -o "$tmp/bad"
expect_exit 1 "medium" dataset --garments tshirt --motions walk --res medium -o "$tmp/bad"
expect_exit 1 "nothere.bvh" dataset --garments tshirt --motions "$tmp/nothere.bvh" -o "$tmp/bad"
expect_exit 2 "missing --motions" dataset --garments tshirt -o "$tmp/bad"
expect_exit 2 "unknown option" dataset --garments tshirt --motions walk --colour red -o "$tmp/bad"

echo "cli_dataset: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
