#!/usr/bin/env bash
# cli.sh: the `crease` tool end to end: outputs, --json summaries, exit codes
# (0 ok, 1 bad input naming file and line, 2 usage) and atomic outputs.
# Usage: cli.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

# --- help and usage -------------------------------------------------------------------
check "top-level help" "$crease" --help
for c in info convert render primitive; do
  check "$c --help" bash -c "'$crease' $c --help | grep -q usage"
done
expect_exit 2 "unknown command" frobnicate
expect_exit 2 "unknown option" info --bogus x.obj
expect_exit 2 "missing -o" primitive sphere
expect_exit 2 "expects an integer" primitive sphere --res abc -o "$tmp/s.obj"
expect_exit 2 "unknown primitive" primitive teapot -o "$tmp/t.obj"
# the option conventions every command shares (src/cli/cli.h, docs/cli.md)
check "--opt=V and --output=" "$crease" primitive sphere --res=8 --output="$tmp/eq.obj"
check "--opt=V wrote" test -s "$tmp/eq.obj"
check "-- ends the options" "$crease" info -- "$tmp/eq.obj"
expect_exit 2 "info: unknown option '--bogus'" info --bogus=3 "$tmp/eq.obj"
expect_exit 2 "option --json takes no value" info --json=1 "$tmp/eq.obj"
expect_exit 2 "option --frames needs a value" simulate --frames
expect_exit 2 "--res expects an integer in \[2, 4096\], got '8x'" primitive sphere --res 8x -o "$tmp/x.obj"
expect_exit 2 "--yaw expects a number in .*, got 'inf'" render "$tmp/eq.obj" --yaw=inf -o "$tmp/x.png"
expect_exit 2 "--color-by expects curvature or height, got 'foo'" render "$tmp/eq.obj" --color-by foo -o "$tmp/x.png"
expect_exit 2 "option --range needs 2 values" render "$tmp/eq.obj" -o "$tmp/x.png" --range 1
expect_exit 2 "too many arguments: 'b.obj'" info "$tmp/eq.obj" b.obj
expect_exit 2 "unexpected argument 'stray'" fit --model grid stray -o "$tmp/f"

# --- primitives, info, convert ----------------------------------------------------------
for k in plane sphere icosphere torus prism box capsule cylinder; do
  check "primitive $k" bash -c "'$crease' primitive $k -o '$tmp/$k.obj' --json > '$tmp/$k.json'"
  check "primitive $k json" json_has "$tmp/$k.json" kind vertices faces output
done
check "info json" bash -c "'$crease' info '$tmp/sphere.obj' --json > '$tmp/info.json'"
check "info fields" json_has "$tmp/info.json" vertices faces bounds manifold boundary_loops has_uv \
  min_angle_deg
check "info closed sphere" grep -q '"boundary_loops":0' "$tmp/info.json"
check "info plane has one boundary loop" bash -c \
  "'$crease' info '$tmp/plane.obj' --json | grep -q '\"boundary_loops\":1'"
check "convert obj->ply" "$crease" convert "$tmp/torus.obj" "$tmp/torus.ply"
check "convert ply->glb" "$crease" convert "$tmp/torus.ply" "$tmp/torus.glb"
check "convert glb->obj" "$crease" convert "$tmp/torus.glb" "$tmp/torus2.obj" --json
check "round trip keeps counts" bash -c \
  "[[ \$('$crease' info '$tmp/torus.obj' --json | grep -o '\"faces\":[0-9]*') == \
     \$('$crease' info '$tmp/torus2.obj' --json | grep -o '\"faces\":[0-9]*') ]]"
# a vertex at (1, 2, 3), scaled by 0.01 and turned from Z-up: (0.01, 0.03, -0.02)
printf 'v 1 2 3\nv 2 2 3\nv 1 3 3\nf 1 2 3\n' > "$tmp/zup_cm.obj"
check "convert --scale --z-up" bash -c "'$crease' convert '$tmp/zup_cm.obj' '$tmp/yup_m.obj' \
  --scale 0.01 --z-up && grep -q '^v 0.00999999978 0.0299999993 -0.0199999996' '$tmp/yup_m.obj'"
expect_exit 2 "apply to meshes" convert "$tmp/x.pc2" "$tmp/x.glb" --rest "$tmp/torus.obj" --scale 2

# --- render ---------------------------------------------------------------------------
check "render" "$crease" render "$tmp/torus.obj" "$tmp/sphere.obj" --wire -o "$tmp/r.png" --size 256
check "render png magic" bash -c "head -c 4 '$tmp/r.png' | grep -q PNG"
check "render colour map" bash -c \
  "'$crease' render '$tmp/torus.obj' --color-by curvature --size 128 -o '$tmp/c.png' --json | grep -q '\"output\"'"
check "turntable" "$crease" render "$tmp/sphere.obj" --turntable 3 --size 64 -o "$tmp/turn.png"
check "turntable frames" test -f "$tmp/turn_002.png"

# --- fit (drape paper, Table 1), tiny --------------------------------------------------
small_fit=(--epochs 2 --train-res 16 --eval-res 16 --batch 64 --quiet)
check "fit grid" bash -c "'$crease' fit --model grid -o '$tmp/fit' ${small_fit[*]} --json > '$tmp/fit.json'"
check "fit fields" json_has "$tmp/fit.json" model params epochs seconds rel_l2 epochs_to_target \
  seconds_to_target surface_png
check "fit params" grep -q '"params":47369' "$tmp/fit.json"
check "fit outputs" test -s "$tmp/fit/checkpoint.safetensors" -a -s "$tmp/fit/surface.png" \
  -a -s "$tmp/fit/log.jsonl"
check "fit resume" bash -c "'$crease' fit --model grid -o '$tmp/fit' --resume --epochs 4 --train-res 16 --eval-res 16 --batch 64 --quiet --json | grep -q '\"resumed_from_epoch\":2'"
expect_exit 1 "checkpoint.safetensors: .*not a parameter" fit --model mlp -o "$tmp/fit" --resume "${small_fit[@]}"
check "fit log: epochs 1-4 after the resume" epochs_are "$tmp/fit/log.jsonl" 4
# a run killed after logging an epoch it did not checkpoint: the resume logs it once
echo '{"epoch":5,"loss":1}' >> "$tmp/fit/log.jsonl"
check "fit resume after a kill" "$crease" fit --model grid -o "$tmp/fit" --resume --epochs 6 \
  --train-res 16 --eval-res 16 --batch 64 --quiet
check "fit log: epochs 1-6" epochs_are "$tmp/fit/log.jsonl" 6
# an edited checkpoint: refused, naming the file and the key
mkdir -p "$tmp/fit_cfg"
st_meta_sub "$tmp/fit/checkpoint.safetensors" "$tmp/fit_cfg/checkpoint.safetensors" config \
  '"seconds"' '"secs"'
expect_exit 1 "fit_cfg/checkpoint.safetensors: config 'seconds' is missing" fit --model grid \
  -o "$tmp/fit_cfg" --resume "${small_fit[@]}"
st_meta_sub "$tmp/fit/checkpoint.safetensors" "$tmp/fit_cfg/checkpoint.safetensors" config \
  '"eval_seconds":[^,]*' '"eval_seconds":"x"'
expect_exit 1 "fit_cfg/checkpoint.safetensors: config 'eval_seconds' is not a number" fit \
  --model grid -o "$tmp/fit_cfg" --resume "${small_fit[@]}"
check "fit again without --resume: a fresh log" "$crease" fit --model grid -o "$tmp/fit" "${small_fit[@]}"
check "fit log: epochs 1-2" epochs_are "$tmp/fit/log.jsonl" 2
expect_exit 2 "unknown model" fit --model siren -o "$tmp/fit2"
expect_exit 2 "missing -o" fit --model grid

# --- bad input: exit 1 with the file (and line) named, nothing written -------------------
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n' > "$tmp/short_face.obj"
expect_exit 1 "short_face.obj:4" info "$tmp/short_face.obj"
printf 'v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n' > "$tmp/nan.obj"
expect_exit 1 "nan.obj:2" info "$tmp/nan.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n' > "$tmp/range.obj"
expect_exit 1 "range.obj:4" convert "$tmp/range.obj" "$tmp/range.ply"
check "no output after failed convert" test ! -e "$tmp/range.ply"
: > "$tmp/empty.obj"
expect_exit 1 "empty.obj" info "$tmp/empty.obj"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n' > "$tmp/huge.ply"
expect_exit 1 "huge.ply" info "$tmp/huge.ply"
printf 'v 0 0 0\n\xff\xfe\x80\x01garbage\x00\n' > "$tmp/garbage.obj"
expect_exit 1 "garbage.obj:2" info "$tmp/garbage.obj"
expect_exit 1 "missing.obj" info "$tmp/missing.obj"
expect_exit 1 "xyz" convert "$tmp/sphere.obj" "$tmp/sphere.xyz"

# docs/cli.md is the reference of every command: every option a command's --help lists is in it
check "docs/cli.md lists every option of every command" bash -c '
  c="$1"; doc="$2"; bad=0
  for cmd in $("$c" --help | awk "/^commands:/{f=1;next} f && /^  [a-z]/{print \$1}"); do
    for o in $("$c" "$cmd" --help 2>&1 | grep -o -- "--[a-z][a-z0-9-]*" | sort -u); do
      grep -q -- "$o" "$doc" || { echo "docs/cli.md misses $cmd $o"; bad=1; }
    done
  done
  exit $bad' _ "$crease" "$(dirname "$0")/../docs/cli.md"
# the generated blocks of docs/cli.md (a documented command's --help, from its option table)
# are what the commands print
check "docs/cli.md's generated option lists equal the commands' --help" \
  python3 "$(dirname "$0")/../scripts/cli_reference.py" "$crease" --check
echo "cli: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
