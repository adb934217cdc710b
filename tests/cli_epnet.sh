#!/usr/bin/env bash
# cli_epnet.sh: `crease epnet train|run` end to end on a small case: the
# physical outcome (the elastic loss terms fall by a stated factor, the
# garment stays outside the body, the rollout stays finite through a hold),
# epnet's RB against the baseline's zero, resume, outputs and exit codes.
# Usage: cli_epnet.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"
export OPENBLAS_NUM_THREADS=1

# a quick run (clang, sanitizers) trains 8 epochs a cycle and leaves the fall of the elastic
# terms to a full run
epochs=$(size 40 8)
small=(--vertices 500 --motions squat --frames 12 --epochs $epochs --pnet-epochs 1 --yield 0.1 --lr 3e-4)

check "epnet --help" bash -c "'$crease' epnet --help | grep -q usage"
check "epnet listed" bash -c "'$crease' --help | grep -q 'epnet '"

check "epnet train" bash -c "'$crease' epnet train ${small[*]} --cycles 2 -o '$tmp/m' --json > '$tmp/t.json'"
check "train fields" json_has "$tmp/t.json" cycles first_loss last_loss first_stretch last_stretch pnet_loss pnet_val_loss
check "train: 2 cycles" grep -q '"cycles":2' "$tmp/t.json"
# stretch + shear + bending of the skinned template fall at least threefold
[[ $quick == 0 ]] && check "elastic terms fall 3x" python3 -c "
import json,sys; j=json.loads(open('$tmp/t.json').read().splitlines()[-1])
f=j['first_stretch']+j['first_shear']+j['first_bending']; l=j['last_stretch']+j['last_shear']+j['last_bending']
sys.exit(0 if l < f/3 else 1)"
check "checkpoints" test -s "$tmp/m/enet.safetensors" -a -s "$tmp/m/pnet.safetensors" -a -s "$tmp/m/model.json"
check "progress lines" bash -c "[[ \$(wc -l < '$tmp/m/progress.jsonl') -eq $((2 * (epochs + 1))) ]]"
check "resume to 3 cycles" bash -c "'$crease' epnet train ${small[*]} --cycles 3 --resume -o '$tmp/m' --json > '$tmp/r.json'"
check "resumed: 3 cycles" grep -q '"cycles":3' "$tmp/r.json"
check "resumed: $((epochs + 1)) more lines" bash -c "[[ \$(wc -l < '$tmp/m/progress.jsonl') -eq $((3 * (epochs + 1))) ]]"

check "epnet run" bash -c "'$crease' epnet run --model '$tmp/m' --motion squat --frames 12 --hold 10 -o '$tmp/o' --json > '$tmp/o.json'"
check "run fields" json_has "$tmp/o.json" frames vertices seconds_per_frame max_abs_rb min_body_distance finite
check "run: finite" grep -q '"finite":true' "$tmp/o.json"
check "run: outside the body (> -5 mm)" python3 -c "
import json,sys; j=json.loads(open('$tmp/o.json').read().splitlines()[-1]); sys.exit(0 if j['min_body_distance'] > -0.005 else 1)"
check "run outputs" test -s "$tmp/o/garment.pc2" -a -s "$tmp/o/garment.glb" -a -s "$tmp/o/garment.png" \
  -a -s "$tmp/o/rb.png" -a -s "$tmp/o/rb.npy"
check "closed-loop run" bash -c "'$crease' epnet run --model '$tmp/m' --motion squat --frames 12 --closed-loop -o '$tmp/c' --json | grep -q '\"finite\":true'"
check "proxy run with its options" bash -c "'$crease' epnet run --model '$tmp/m' --motion squat --frames 12 --drive 0.1 --min-delta 0.01 --warmup 5 -o '$tmp/p' --json | grep -q '\"finite\":true'"
check "baseline run: RB 0" bash -c "'$crease' epnet run --model '$tmp/m' --motion squat --frames 12 --baseline -o '$tmp/b' --json | grep -q '\"max_abs_rb\":0'"
# Table 1 against the reference and its twin, on a short held-out clip
check "baseline train" "$crease" epnet train ${small[*]} --cycles 1 --baseline -o "$tmp/bl"
check "epnet measure" bash -c "'$crease' epnet measure --models '$tmp/m' --baselines '$tmp/bl' \
  --motions bend --bodies normal --frames 10 --hold 2 -o '$tmp/meas' > '$tmp/meas.md'"
check "the twin row and the baseline's error removed" bash -c "grep -q '| twin' '$tmp/meas.md' && \
  grep -q 'epnet (baseline: the first zero-RB seed)' '$tmp/meas.md'"
check "tables as JSON, the picture" bash -c "[[ -s '$tmp/meas/table_epnet_bend_normal.json' && \
  -s '$tmp/meas/table_baseline_bend_normal.json' && -s '$tmp/meas/side_by_side_bend.png' ]]"
expect_exit 2 "--models, --baselines and -o are required" epnet measure --models "$tmp/m" -o "$tmp/x"
expect_exit 1 "none/model.json" epnet measure --models "$tmp/none" --baselines "$tmp/bl" -o "$tmp/x"

# a garment mesh of one's own, without UVs: trained (one short cycle) and run
"$crease" garment --type skirt --res 600 -o "$tmp/skirt.obj" >/dev/null 2>&1
awk '$1 == "vt" { next } $1 == "f" { for (i = 2; i <= NF; i++) { split($i, p, "/"); $i = p[1] } } { print }' \
  "$tmp/skirt.obj" > "$tmp/skirt_nouv.obj"
check "train on a garment file without UVs" "$crease" epnet train --garment "$tmp/skirt_nouv.obj" \
  --motions squat --frames 8 --epochs 2 --pnet-epochs 1 --cycles 1 -o "$tmp/mf"
check "run it" bash -c "'$crease' epnet run --model '$tmp/mf' --motion squat --frames 8 -o '$tmp/of' --json | \
  grep -q '\"finite\":true'"

expect_exit 2 "-o DIR is required" epnet train
expect_exit 2 "expected train, run or measure" epnet fly
expect_exit 1 "model.json" epnet run --model "$tmp/none" --motion squat -o "$tmp/x"
# a model folder from before the RB paths were pruned: off, it loads; on, it is refused
cp -r "$tmp/m" "$tmp/old"
sed -i 's/"w_bending": \([^,]*\),/"w_bending": \1, "rb_fold": 0, "rb_augment": 0,/' "$tmp/old/model.json"
check "an old model with the pruned options off runs" bash -c "'$crease' epnet run --model '$tmp/old' \
  --motion squat --frames 4 -o '$tmp/old_run' > /dev/null 2>&1"
sed -i 's/"rb_fold": 0/"rb_fold": 1/' "$tmp/old/model.json"
expect_exit 1 "model.json: the model was trained with an option since removed.*rb_fold" epnet run \
  --model "$tmp/old" --motion squat --frames 4 -o "$tmp/x"

echo "cli_epnet: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
