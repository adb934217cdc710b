#!/usr/bin/env bash
# cli_swingar_sdf.sh: `crease swingar-sdf train|measure` end to end at toy sizes: a
# tiny model trains and resumes (the step count carries over), measure reports its
# fields, the exact removal leaves no vertex inside, usage errors exit 2 and a missing
# model file exits 1 naming it.
# Usage: cli_swingar_sdf.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

check "swingar-sdf --help" bash -c "'$crease' swingar-sdf --help | grep -q usage"
check "swingar-sdf listed" bash -c "'$crease' --help | grep -q '^  swingar-sdf'"

toy=(--width 8 --batch 32 --frames 6 --stride 3 --surface 100 --near 100 --space 20
     --resolution 60 --quiet)
check "train" bash -c "'$crease' swingar-sdf train -o '$tmp/sdf.safetensors' ${toy[*]} \
  --steps 4 --stop-at 2 --json > '$tmp/a.json'"
check "train fields" json_has "$tmp/a.json" poses samples steps loss value_m normal eikonal
check "train articulated" bash -c "'$crease' swingar-sdf train -o '$tmp/art.safetensors' \
  ${toy[*]} --steps 2 --articulated 2 --json | grep -q '\"articulated\":2,'"
check "train resumes" bash -c "'$crease' swingar-sdf train -o '$tmp/sdf.safetensors' ${toy[*]} \
  --steps 4 --resume --json | grep -q '\"resumed_from\":2,'"
check "measure" bash -c "'$crease' swingar-sdf measure --model '$tmp/sdf.safetensors' \
  --frames 6 --first 1 --stride 4 --max-frames 2 --resolution 60 --garment tshirt \
  --garment-vertices 1500 --quiet --json > '$tmp/m.json'"
check "measure fields" json_has "$tmp/m.json" err_mean_mm ratio_before_pct ratio_neural_pct \
  ratio_exact_pct ms_neural ms_exact
check "exact removal clears" json_below "$tmp/m.json" ratio_exact_pct 1e-9
json_above() { ! json_below "$@"; } # the key's number is at least the limit (or missing: use json_has first)
# a recorded sequence: a shorter slim mannequin posed by the same clip stands in for a
# predicted garment (most of it inside the taller body)
pb=(pose-body --clip twist --frames 6 --res 60 --shape slim --ground none)
check "body pc2" "$crease" "${pb[@]}" -o "$tmp/body.pc2"
check "garment pc2" "$crease" "${pb[@]}" --height 1.6 --res 56 -o "$tmp/small.pc2"
seq=(--motions twist --frames 6 --shape slim --resolution 60 --first 0 --stride 2
     --garment-pc2 "$tmp/small.pc2" --garment-mesh "$tmp/small.obj" --body-pc2 "$tmp/body.pc2")
check "measure a sequence" bash -c "'$crease' swingar-sdf measure --model '$tmp/sdf.safetensors'   ${seq[*]} --body-mesh '$tmp/body.obj' --quiet --json > '$tmp/s.json'"
check "sequence fields" json_has "$tmp/s.json" ratio_before_pct ratio_neural_pct ms_neural
check "sequence: inside before" json_above "$tmp/s.json" ratio_before_pct 10
check "sequence: exact removal clears" json_below "$tmp/s.json" ratio_exact_pct 1e-9
expect_exit 1 "small.obj has" swingar-sdf measure --model "$tmp/sdf.safetensors" "${seq[@]}" \
  --body-mesh "$tmp/small.obj"

expect_exit 2 "train' or 'measure'" swingar-sdf fly
expect_exit 2 "missing -o" swingar-sdf train --steps 2
expect_exit 2 "missing --model" swingar-sdf measure
expect_exit 1 "nope.safetensors" swingar-sdf measure --model "$tmp/nope.safetensors"

echo "cli_swingar_sdf: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
