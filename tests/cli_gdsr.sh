#!/usr/bin/env bash
# cli_gdsr.sh: `crease gdsr` end to end on a small case: a 500 / 1,000-vertex
# t-shirt pair simulated on two short clips, a small model trained on one
# (walk), resumed, then rolled out on the held-out one (dance). Physical
# outcome checked: on the held-out clip the super-resolved garment is closer
# to the high-resolution simulation than the barycentric upsampling of the
# low-resolution input (mean vertex distance at most 97 % of upsampling's),
# and after collision handling under 0.1 % of its vertices are inside the
# body on any frame. Exit codes: 2 for usage, 1 for a missing dataset.
# Usage: cli_gdsr.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"
export OMP_WAIT_POLICY=passive

check "gdsr --help" bash -c "'$crease' gdsr --help | grep -q usage"
check "gdsr listed" bash -c "'$crease' --help | grep -q 'gdsr '"
expect_exit 2 "subcommand" gdsr
expect_exit 2 "missing --dataset" gdsr train --motions walk -o "$tmp/m"
expect_exit 1 "tshirt_low.obj" gdsr train --dataset "$tmp/none" --motions walk -o "$tmp/m"

check "dataset" "$crease" dataset --garments tshirt --motions walk,dance --res low,high \
  --low-vertices 500 --high-vertices 1000 --frames 16 --quiet -o "$tmp/data"
small=(--dataset "$tmp/data" --motions walk --latent 32 --steps 2 --wire-width 8 --lr 0.002
       --quiet)
check "gdsr train 3 epochs" bash -c "'$crease' gdsr train ${small[*]} --epochs 3 -o '$tmp/m' --json > '$tmp/t1.json'"
check "gdsr train resumes to 12" bash -c "'$crease' gdsr train ${small[*]} --epochs 12 --resume -o '$tmp/m' --json > '$tmp/t2.json'"
check "train fields" json_has "$tmp/t2.json" command params epochs resumed_from first_loss loss \
  coarse_l1_m fine_l1_m normal_l1 seconds
check "resumed from 3" grep -q '"resumed_from":3,' "$tmp/t2.json"
check "log: 12 lines" bash -c "[[ \$(wc -l < '$tmp/m/log.jsonl') -eq 12 ]]"
check "gdsr run held-out" bash -c "'$crease' gdsr run --dataset '$tmp/data' --motion dance --model '$tmp/m/model.safetensors' -o '$tmp/r' --quiet --json > '$tmp/r.json'"
check "run outputs" test -s "$tmp/r/gdsr.pc2" -a -s "$tmp/r/upsampled.pc2" -a -s "$tmp/r/high.obj" \
  -a -s "$tmp/r/summary.json"
# mean vertex distance: the first med_m is upsampling's, the second gdsr's
meds=$(grep -o '"med_m":[-0-9.eE+]*' "$tmp/r.json" | cut -d: -f2 | tr '\n' ' ')
check "gdsr closer than upsampling on held-out frames ($meds)" \
  awk -v s="$meds" 'BEGIN { split(s, a, " "); exit !(a[2] < 0.97 * a[1]) }'
check "under 0.1 % inside after handling" json_below "$tmp/r.json" inside_after 0.001

echo "cli_gdsr: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
