#!/usr/bin/env bash
# cli_drape.sh: `crease drape` end to end on coarse settings: outputs, the
# --json summary, resume, --compare, and exit codes (0 ok, 1 bad input naming
# the file, 2 usage naming the option).
# Usage: cli_drape.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

# coarse: a small network, few structures, a small evaluation set
small=(--grid-res 16 --hidden 16 --mesh-res 20 --samples 96 --pdf-grid 8 --pdf-every 2 --lloyd 1
       --eval-res 12 --eval-every 10 --res 24 --render-size 64 --gap 0.01 --lr 0.003
       --lr-final 1e-6 --quiet)

check "drape --help" bash -c "'$crease' drape --help | grep -q usage"
check "drape listed" bash -c "'$crease' --help | grep -q 'drape '"

# --- one run ---------------------------------------------------------------------------
check "drape ball" bash -c "'$crease' drape --scene ball --epochs 30 ${small[*]} -o '$tmp/a' --json > '$tmp/a.json'"
check "drape fields" json_has "$tmp/a.json" command scene variant params epochs seconds \
  converged_epoch strain bend gravity collision total max_penetration_m facet_ratio grid_interp \
  outputs obj glb png loss_png log sampler_png checkpoint
check "drape variant" grep -q '"variant":"inr-adaptive"' "$tmp/a.json"
check "drape grid interpolation" grep -q '"grid_interp":"bspline"' "$tmp/a.json"
check "drape epochs" grep -q '"epochs":30,' "$tmp/a.json"
check "drape penetration < 1 mm" json_below "$tmp/a.json" max_penetration_m 1e-3
check "drape outputs" test -s "$tmp/a/drape.obj" -a -s "$tmp/a/drape.glb" -a -s "$tmp/a/drape.png" \
  -a -s "$tmp/a/loss.png" -a -s "$tmp/a/sampler.png" -a -s "$tmp/a/checkpoint.safetensors"
check "drape log: 4 lines" bash -c "[[ \$(wc -l < '$tmp/a/loss.jsonl') -eq 4 ]]"
check "drape log fields" json_has "$tmp/a/loss.jsonl" epoch seconds strain bend gravity collision \
  total train_total
check "drape obj at --res" bash -c "[[ \$(grep -c '^v ' '$tmp/a/drape.obj') -eq 576 ]]"

# --- resume: 30 more epochs continue the log ---------------------------------------------
check "drape resume" bash -c "'$crease' drape --scene ball --epochs 60 ${small[*]} -o '$tmp/a' --resume --json > '$tmp/b.json'"
check "drape resumed from 30" grep -q '"resumed_from_epoch":30' "$tmp/b.json"
check "drape resumed to 60" grep -q '"epochs":60,' "$tmp/b.json"
check "drape resumed log: 7 lines" bash -c "[[ \$(wc -l < '$tmp/a/loss.jsonl') -eq 7 ]]"

# --- other variants and scenes -----------------------------------------------------------
check "drape mesh torus" bash -c "'$crease' drape --scene torus --variant mesh --epochs 10 ${small[*]} -o '$tmp/m' --json > '$tmp/m.json'"
check "drape mesh free variables" grep -q '"params":1200,' "$tmp/m.json"
check "drape sdf prism" "$crease" drape --scene prism --variant inr-uniform --collision sdf --epochs 5 \
  "${small[@]}" -o "$tmp/p"
"$crease" primitive sphere -o "$tmp/obj.obj" >/dev/null
check "drape --object" bash -c "'$crease' drape --object '$tmp/obj.obj' --variant inr-mesh --epochs 5 ${small[*]} -o '$tmp/o' --json > '$tmp/o.json'"
check "drape --object scene name" grep -q "\"scene\":\"$tmp/obj.obj\"" "$tmp/o.json"

# --- compare: four variants, one picture ---------------------------------------------------
check "drape --compare" bash -c "'$crease' drape --scene table --compare --epochs 5 ${small[*]} -o '$tmp/c' --json > '$tmp/c.json'"
check "drape compare png" test -s "$tmp/c/compare.png"
check "drape compare dirs" test -s "$tmp/c/mesh/drape.obj" -a -s "$tmp/c/inr-mesh/drape.obj" \
  -a -s "$tmp/c/inr-uniform/drape.obj" -a -s "$tmp/c/inr-adaptive/drape.obj"
check "drape compare json" json_has "$tmp/c.json" compare_png variants

# --- bad input ---------------------------------------------------------------------------
expect_exit 2 "missing -o" drape --scene ball
expect_exit 2 "--scene.*'cube'" drape --scene cube -o "$tmp/x"
expect_exit 2 "--variant.*'inr'" drape --variant inr -o "$tmp/x"
expect_exit 2 "--lr expects a number" drape --lr nan -o "$tmp/x"
expect_exit 2 "--w-collision expects a number" drape --w-collision inf -o "$tmp/x"
expect_exit 2 "--epochs expects an integer" drape --epochs 0 -o "$tmp/x"
expect_exit 2 "exclude each other" drape --scene ball --object "$tmp/obj.obj" -o "$tmp/x"
expect_exit 2 "--collision expects vertex or sdf" drape --collision box -o "$tmp/x"
expect_exit 2 "unknown option '--frobnicate'" drape --frobnicate -o "$tmp/x"
expect_exit 1 "missing.obj" drape --object "$tmp/missing.obj" --epochs 1 "${small[@]}" -o "$tmp/x"
printf 'v 0 1 0\nv 1 1 0\nv 0 1 1\nf 1 3 2\n' > "$tmp/nouv.obj"
expect_exit 1 "nouv.obj.*no UVs" drape --cloth "$tmp/nouv.obj" --epochs 1 "${small[@]}" -o "$tmp/x"
# a vertex no face uses would size the cloth: refused, naming the file and the vertex
cp "$tmp/obj.obj" "$tmp/unref.obj" && echo 'v 100 100 100' >> "$tmp/unref.obj"
nv=$(grep -c '^v ' "$tmp/unref.obj")
expect_exit 1 "unref.obj: vertex $nv \\(counting from 1\\) is used by no face" drape \
  --object "$tmp/unref.obj" --epochs 1 "${small[@]}" -o "$tmp/x"
"$crease" primitive plane --size 1 --res 8 -o "$tmp/cloth.obj" >/dev/null
cp "$tmp/cloth.obj" "$tmp/cloth_unref.obj" && echo 'v 5 5 5' >> "$tmp/cloth_unref.obj"
expect_exit 1 "cloth_unref.obj: vertex 65 \\(counting from 1\\)" drape --cloth "$tmp/cloth_unref.obj" \
  --epochs 1 "${small[@]}" -o "$tmp/x"
# an object or cloth in centimetres is draped, with a warning naming its size
"$crease" primitive box --size 50 --subdiv 2 -o "$tmp/box_cm.obj" >/dev/null
check "drape object in cm warns" bash -c "'$crease' drape --object '$tmp/box_cm.obj' --epochs 1 \
  ${small[*]} -o '$tmp/cm' 2>&1 >/dev/null | grep -q 'warning: --object .*box_cm.obj: 50 m across.*centimetres it is 0.5 m'"
"$crease" primitive plane --size 100 --res 8 -o "$tmp/cloth_cm.obj" >/dev/null
check "drape cloth in cm warns" bash -c "'$crease' drape --cloth '$tmp/cloth_cm.obj' --epochs 1 \
  ${small[*]} -o '$tmp/cm' 2>&1 >/dev/null | grep -q 'warning: --cloth .*cloth_cm.obj: 100 m across'"
check "drape object in m does not warn" bash -c "! '$crease' drape --object '$tmp/obj.obj' --cloth '$tmp/cloth.obj' \
  --epochs 1 ${small[*]} -o '$tmp/m1' 2>&1 | grep -q warning"
# an open object (a quad) has no inside: the penetration is not measured (null), with a warning
printf 'v -0.5 0 -0.5\nv 0.5 0 -0.5\nv 0.5 0 0.5\nv -0.5 0 0.5\nf 1 4 3 2\n' > "$tmp/quad.obj"
check "open object: warned, no depth" bash -c "'$crease' drape --object '$tmp/quad.obj' --epochs 1 \
  ${small[*]} --json -o '$tmp/quad' 2>'$tmp/quad.err' | grep -q '\"max_penetration_m\":null' \
  && grep -q 'quad.obj is open (4 boundary edges)' '$tmp/quad.err'"
expect_exit 1 "a checkpoint of variant 'inr-adaptive'" drape --scene ball --variant inr-uniform \
  --epochs 31 "${small[@]}" -o "$tmp/a" --resume
expect_exit 1 "a checkpoint of the bspline grid encoding, not bilinear" drape --scene ball \
  --grid-interp bilinear --epochs 61 "${small[@]}" -o "$tmp/a" --resume
expect_exit 2 "--grid-interp" drape --grid-interp cubic -o "$tmp/x"

echo "cli_drape: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
