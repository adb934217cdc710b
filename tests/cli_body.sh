#!/usr/bin/env bash
# cli_body.sh: `crease body` and `crease pose-body` end to end: meshes in each
# format, --json fields and values (watertight, height, counts), PC2 and .glb
# sequences from a clip and from a motion file, and exit codes (0 ok, 1 bad
# input naming the file, 2 usage).
# Usage: cli_body.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

json_num() { # json_num FILE KEY: the number at KEY in FILE's last line
  tail -n 1 "$1" | grep -o "\"$2\":[-0-9.eE+]*" | head -n 1 | cut -d: -f2
}

# json_between FILE KEY LO HI: LO <= number at KEY <= HI
json_between() {
  local v; v=$(json_num "$1" "$2")
  [[ -n $v ]] && awk -v v="$v" -v lo="$3" -v hi="$4" 'BEGIN { exit !(v >= lo && v <= hi) }'
}

for c in body pose-body; do
  check "$c --help" bash -c "'$crease' $c --help | grep -q usage"
done

# --- body: the default mannequin --------------------------------------------------------
check "body" bash -c "'$crease' body --json -o '$tmp/body.obj' > '$tmp/body.json'"
check "body fields" json_has "$tmp/body.json" command vertices faces height_m watertight output seconds
check "body watertight" grep -q '"watertight":true' "$tmp/body.json"
check "body 1.75 m" json_between "$tmp/body.json" height_m 1.745 1.755
check "body 7k-12k vertices" json_between "$tmp/body.json" vertices 7000 12000
check "body obj" grep -q '^f ' "$tmp/body.obj"
check "body info: manifold" bash -c "'$crease' info '$tmp/body.obj' --json | grep -q '\"manifold\":true'"

# --- shapes, options and formats ---------------------------------------------------------
check "heavy ply" bash -c "'$crease' body --shape heavy --res 64 --json -o '$tmp/heavy.ply' > '$tmp/heavy.json'"
check "heavy ply magic" bash -c "head -c 3 '$tmp/heavy.ply' | grep -q ply"
check "slim glb 1.6 m" bash -c "'$crease' body --shape slim --height 1.6 --res 64 --json -o '$tmp/slim.glb' > '$tmp/slim.json'"
check "body glb skinned" bash -c "head -c 4000 '$tmp/slim.glb' | grep -aq '\"joints\":\[1,2,3'"
check "slim height" json_between "$tmp/slim.json" height_m 1.595 1.605
check "slim glb magic" bash -c "head -c 4 '$tmp/slim.glb' | grep -q glTF"
check "override after preset" bash -c "'$crease' body --girth 1.3 --shape slim --chest 1.2 --hips 0.9 \
  --arm-angle 30 --res 64 -o '$tmp/mix.obj'"

# --- pose-body: a clip to PC2 (with the rest mesh) and to .glb ---------------------------
check "pose-body pc2" bash -c "'$crease' pose-body --clip walk --frames 5 --res 64 -o '$tmp/walk.pc2' \
  --json > '$tmp/walk.json'"
check "pose-body fields" json_has "$tmp/walk.json" command frames fps vertices faces paths seconds
check "pose-body 5 frames" grep -q '"frames":5,' "$tmp/walk.json"
check "pose-body paths" grep -q "walk.pc2\",\"$tmp/walk.obj\"" "$tmp/walk.json"
check "pose-body files" test -s "$tmp/walk.pc2" -a -s "$tmp/walk.obj"
# PC2: a 32-byte header then 5 frames of V points of 3 floats
check "pc2 size" bash -c "v=\$(grep -o '\"vertices\":[0-9]*' '$tmp/walk.json' | cut -d: -f2); \
  [[ \$(stat -c %s '$tmp/walk.pc2') -eq \$((32 + 5 * v * 12)) ]]"
check "pose-body glb" bash -c "'$crease' pose-body --shape heavy --clip squat --frames 4 --fps 24 \
  --res 64 -o '$tmp/squat.glb' --json > '$tmp/squat.json'"
check "glb fps" grep -q '"fps":24,' "$tmp/squat.json"
check "glb magic" bash -c "head -c 4 '$tmp/squat.glb' | grep -q glTF"
check "glb skinned" bash -c "head -c 4000 '$tmp/squat.glb' | grep -aq '\"skins\":\[{\"inverseBindMatrices\"'"
check "glb plays back" bash -c "'$crease' info '$tmp/squat.glb' > /dev/null"
# a motion file written by `crease motion`, cut to its first 3 frames
"$crease" motion --clip jump --frames 8 -o "$tmp/jump.npz" >/dev/null 2>&1
check "pose-body --motion" bash -c "'$crease' pose-body --motion '$tmp/jump.npz' --frames 3 --res 64 \
  -o '$tmp/jump.pc2' --json > '$tmp/jump.json'"
check "motion frames cut" grep -q '"frames":3,' "$tmp/jump.json"
# a file resampled to 60 fps (8 frames at 30 are 15 at 60), with and without the 1 s ease-in
check "pose-body --fps" bash -c "'$crease' pose-body --motion '$tmp/jump.npz' --fps 60 --ease-in 0 \
  --res 64 -o '$tmp/jump60.pc2' --json > '$tmp/jump60.json'"
check "resampled frames" grep -q '"frames":15,' "$tmp/jump60.json"
check "source rate" grep -q '"source_fps":30,' "$tmp/jump60.json"
check "pose-body ease-in" bash -c "'$crease' pose-body --motion '$tmp/jump.npz' --res 64 \
  -o '$tmp/jumpe.pc2' --json | grep -q '\"ease_in_frames\":30,'"

# --- bad input and usage -----------------------------------------------------------------
expect_exit 2 "unknown shape 'fat'" body --shape fat -o "$tmp/x.obj"
expect_exit 2 "--height" body --height 3 -o "$tmp/x.obj"
expect_exit 2 "--res" body --res 8 -o "$tmp/x.obj"
expect_exit 2 "missing -o" body
expect_exit 2 "unknown option" body --colour red -o "$tmp/x.obj"
expect_exit 1 "stl" body --res 64 -o "$tmp/x.stl"
expect_exit 1 "too coarse" body --shape slim --girth 0.7 --res 40 -o "$tmp/x.obj"
expect_exit 2 "one of --clip" pose-body -o "$tmp/x.pc2"
expect_exit 2 "one of --clip" pose-body --clip walk --motion "$tmp/jump.npz" -o "$tmp/x.pc2"
expect_exit 2 "unknown clip" pose-body --clip moonwalk -o "$tmp/x.pc2"
expect_exit 2 "expected .pc2 or .glb" pose-body --clip walk -o "$tmp/x.obj"
expect_exit 2 "--rest" pose-body --motion "$tmp/jump.npz" --rest upright -o "$tmp/x.pc2"
expect_exit 2 "--ground" pose-body --motion "$tmp/jump.npz" --ground floor -o "$tmp/x.pc2"
expect_exit 2 "read a --motion file" pose-body --clip walk --scale 0.01 -o "$tmp/x.pc2"
expect_exit 1 "missing.npz" pose-body --motion "$tmp/missing.npz" --res 64 -o "$tmp/x.pc2"

echo "cli_body: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
