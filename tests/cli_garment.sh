#!/usr/bin/env bash
# cli_garment.sh: `crease garment` end to end: a t-shirt with its --json
# figures (vertex count, triangle quality, clearance), a picture, layers,
# formats, a user garment fitted back onto the body, and exit codes (0 ok,
# 1 bad input naming the file, 2 usage). Small garments on a coarse body.
# Usage: cli_garment.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

json_num() { # json_num FILE KEY: the first number at KEY in FILE's last line
  tail -n 1 "$1" | grep -o "\"$2\":[-0-9.eE+]*" | head -n 1 | cut -d: -f2
}

# json_between FILE KEY LO HI: LO <= number at KEY <= HI
json_between() {
  local v; v=$(json_num "$1" "$2")
  [[ -n $v ]] && awk -v v="$v" -v lo="$3" -v hi="$4" 'BEGIN { exit !(v >= lo && v <= hi) }'
}

check "garment --help" bash -c "'$crease' garment --help | grep -q usage"
fast=(--body-res 72 --res 2000)

# --- a t-shirt with a picture -----------------------------------------------------------
check "tshirt" bash -c "'$crease' garment --type tshirt ${fast[*]} -o '$tmp/t.obj' --render '$tmp/t.png' \
  --size 160 --json > '$tmp/t.json'"
check "tshirt fields" json_has "$tmp/t.json" command type vertices faces share_min_angle_above_20deg \
  min_angle_deg min_clearance_m boundary_loops panels uv_scale_m paths seconds
check "tshirt 2000 +- 15%" json_between "$tmp/t.json" vertices 1700 2300
check "tshirt angles" json_between "$tmp/t.json" share_min_angle_above_20deg 0.99 1
check "tshirt clearance >= 5 mm" json_between "$tmp/t.json" min_clearance_m 0.005 0.1
check "tshirt 4 openings" grep -q '"boundary_loops":4,' "$tmp/t.json"
check "tshirt paths" grep -q "\"paths\":\[\"$tmp/t.obj\",\"$tmp/t.png\"\]" "$tmp/t.json"
check "tshirt obj has UVs" grep -q '^vt ' "$tmp/t.obj"
check "tshirt png magic" bash -c "head -c 4 '$tmp/t.png' | grep -q PNG"
check "tshirt manifold" bash -c "'$crease' info '$tmp/t.obj' --json | grep -q '\"manifold\":true'"

# --- layers, formats, options -----------------------------------------------------------
check "layers" bash -c "'$crease' garment --type tshirt,vest ${fast[*]} -o '$tmp/l.ply' --json > '$tmp/l.json'"
check "layers files" test -s "$tmp/l_tshirt.ply" -a -s "$tmp/l_vest.ply"
check "layers listed" json_has "$tmp/l.json" layers
check "skirt glb posed picture" bash -c "'$crease' garment --type skirt --flare 20 --length 0.8 ${fast[*]} \
  -o '$tmp/s.glb' --render '$tmp/s.png' --size 128 --clip walk --frame 10 2>/dev/null"
check "skirt glb magic" bash -c "head -c 4 '$tmp/s.glb' | grep -q glTF"

# --- random variants and named shape parameters ------------------------------------------
check "help lists parameters" bash -c "'$crease' garment --help | grep -q -- '--sleeve *0.5 to 1.5'"
check "random dress" bash -c "'$crease' garment --type dress --random --seed 3 --body-res 64 --res 1000 \
  -o '$tmp/r1.obj' --json > '$tmp/r1.json'"
check "random fields" json_has "$tmp/r1.json" params spec seed attempts
check "random dress again" bash -c "'$crease' garment --type dress --random --seed 3 --body-res 64 \
  --res 1000 -o '$tmp/r2.obj' --json > '$tmp/r2.json'"
check "random is seeded" cmp -s "$tmp/r1.obj" "$tmp/r2.obj"
check "random named override" bash -c "'$crease' garment --type dress --random --seed 3 --flare 30 \
  --body-res 64 --res 1000 -o '$tmp/r3.obj' --json | grep -q '\"flare\":30,'"
check "jumpsuit 5 openings" bash -c "'$crease' garment --type jumpsuit --length 0.7 --neck 0.02 \
  --body-res 64 --res 1000 -o '$tmp/j.obj' --json | grep -q '\"boundary_loops\":5,'"
expect_exit 2 "--length expects a number in \\[0.5, 1.5\\]" garment --type dress --length 2 -o "$tmp/x.obj"
expect_exit 2 "--neck expects a number in \\[-0.02, 0.08\\]" garment --type dress --neck 1 -o "$tmp/x.obj"
expect_exit 2 "--seed needs --random" garment --type dress --seed 3 -o "$tmp/x.obj"
expect_exit 2 "not a layer list" garment --type tshirt,vest --random -o "$tmp/x.obj"

# --- a user garment: the t-shirt fitted back onto the body -------------------------------
check "user" bash -c "'$crease' garment --user '$tmp/t.obj' --body-res 72 --clearance 0.012 -o '$tmp/u.obj' \
  --json > '$tmp/u.json'"
check "user clearance" json_between "$tmp/u.json" min_clearance_m 0.0119 0.1
check "user type" grep -q '"type":"user"' "$tmp/u.json"
awk '$1 == "vt" { next } $1 == "f" { for (i = 2; i <= NF; i++) { split($i, p, "/"); $i = p[1] } } { print }' \
  "$tmp/t.obj" > "$tmp/nouv.obj"
# without UVs (as research garments come): fitted all the same, one piece, uv_scale_m 0
check "user without UVs" bash -c "'$crease' garment --user '$tmp/nouv.obj' --body-res 72 \
  -o '$tmp/nouv_fit.obj' --json > '$tmp/nouv.json'"
check "no UVs: one piece" grep -q '"panels":1,' "$tmp/nouv.json"
check "no UVs: clearance" json_between "$tmp/nouv.json" min_clearance_m 0.0099 0.1
check "no UVs: simulated" "$crease" simulate --garment "$tmp/nouv_fit.obj" \
  --motion walk --frames 3 -o "$tmp/nouv_sim" --quiet
# in two pieces (a patch pocket, not sewn on, in front of the chest): two panels, simulated and
# skinned (a swingar model refuses it: its descriptor needs one piece, test_swingar_descriptor)
awk -v n="$(grep -c '^v ' "$tmp/nouv.obj")" '{ print } END {
  printf "v 0.05 1.24 0.2\nv 0.13 1.24 0.2\nv 0.13 1.33 0.2\nv 0.05 1.33 0.2\n"
  printf "f %d %d %d\nf %d %d %d\n", n + 1, n + 2, n + 3, n + 1, n + 3, n + 4 }' \
  "$tmp/nouv.obj" > "$tmp/pocket.obj"
check "two pieces" bash -c "'$crease' garment --user '$tmp/pocket.obj' --body-res 72 \
  -o '$tmp/pocket_fit.obj' --json | grep -q '\"panels\":2,'"
check "two pieces: simulated" "$crease" simulate --garment "$tmp/pocket_fit.obj" --motion walk \
  --frames 2 -o "$tmp/pocket_sim" --quiet
check "two pieces: skinned by swingar run" "$crease" swingar run --skinned \
  --garment "$tmp/pocket_fit.obj" --motion walk --frames 2 -o "$tmp/pocket_skin"
# a skinned glb character moves the collider by its own animation
check "character glb" "$crease" pose-body --clip walk --frames 4 --res 72 -o "$tmp/char.glb"
check "simulated on the character" bash -c "'$crease' simulate --garment '$tmp/nouv_fit.obj' \
  --body-mesh '$tmp/char.glb' --frames 3 -o '$tmp/char_sim' --quiet --json | \
  grep -q '\"max_penetration_m\":0,'"
check "scene.glb: body and garment" bash -c "head -c 3000 '$tmp/nouv_sim/scene.glb' | \
  grep -aq '\"name\":\"garment\"'"
expect_exit 1 "missing.obj" garment --user "$tmp/missing.obj" --body-res 48 -o "$tmp/x.obj"

# --- usage ----------------------------------------------------------------------------------
expect_exit 2 "unknown type 'poncho'" garment --type poncho -o "$tmp/x.obj"
expect_exit 2 "missing -o" garment --type tshirt
expect_exit 2 "one of --type or --user" garment --type tshirt --user "$tmp/t.obj" -o "$tmp/x.obj"
expect_exit 2 "--res" garment --type tshirt --res 10 -o "$tmp/x.obj"
expect_exit 2 "--clearance" garment --type tshirt --clearance 0.001 -o "$tmp/x.obj"
expect_exit 2 "unknown clip" garment --type tshirt --clip moonwalk -o "$tmp/x.obj"
expect_exit 2 "unknown option" garment --type tshirt --colour red -o "$tmp/x.obj"

echo "cli_garment: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
