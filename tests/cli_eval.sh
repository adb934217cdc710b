#!/usr/bin/env bash
# cli_eval.sh: `crease eval` end to end on a short simulation: a sequence against
# itself (every error 0), a rigid translation (MED = d), the report's files, a body,
# the twin (simulate --twin, --friction-delta) and the table of seeds, twin and baseline with
# the fold measures, and bad input (mismatched counts or sizes naming both files, NaN and
# missing files named; exit 1), usage errors (exit 2).
# Usage: cli_eval.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

check "eval --help" bash -c "'$crease' eval --help | grep -q usage"
check "eval listed" bash -c "'$crease' --help | grep -q '^  eval'"

# --- a 12x12 cloth falling onto the sphere for 6 frames --------------------------------
"$crease" primitive plane --res 12 -o "$tmp/cloth.obj" >/dev/null
"$crease" primitive plane --res 10 -o "$tmp/cloth10.obj" >/dev/null
"$crease" primitive sphere -o "$tmp/sphere.obj" >/dev/null
"$crease" simulate --garment "$tmp/cloth.obj" --garment-offset 0,0.35,0 --object sphere \
  --frames 6 -o "$tmp/sim" --quiet >/dev/null
"$crease" simulate --garment "$tmp/cloth10.obj" --garment-offset 0,0.35,0 --object sphere \
  --frames 6 -o "$tmp/sim10" --quiet >/dev/null
"$crease" simulate --garment "$tmp/cloth.obj" --garment-offset 0,0.35,0 --object sphere \
  --frames 3 -o "$tmp/sim3" --quiet >/dev/null

# pc2 edits: translate by (0.03, 0, -0.04) (|d| = 5 cm); in centimetres; one NaN coordinate
python3 - "$tmp" <<'PY'
import struct, sys
tmp = sys.argv[1]
raw = open(f"{tmp}/sim/sim.pc2", "rb").read()
head, body = raw[:32], raw[32:]
n = len(body) // 4
v = list(struct.unpack(f"<{n}f", body))
t = [x + (0.03, 0.0, -0.04)[i % 3] for i, x in enumerate(v)]
open(f"{tmp}/moved.pc2", "wb").write(head + struct.pack(f"<{n}f", *t))
open(f"{tmp}/cm.pc2", "wb").write(head + struct.pack(f"<{n}f", *[100 * x for x in v]))
v[3 * 50 + 1] = float("nan")
open(f"{tmp}/nan.pc2", "wb").write(head + struct.pack(f"<{n}f", *v))
PY

# --- against itself: every error 0, SSIM 1 ------------------------------------------------
check "eval self" bash -c "'$crease' eval --pred '$tmp/sim/sim.pc2' --ref '$tmp/sim/sim.pc2' \
  --garment '$tmp/cloth.obj' -o '$tmp/self' --json > '$tmp/self.json' 2>/dev/null"
check "eval fields" json_has "$tmp/self.json" command frames vertices hinges bed_hinges worst_frame \
  metrics med_m bed_rad be_rad pe_rad cd_m2 chamfer_m ben_j ste_j she_j ge_j ie_j col_m \
  collision_ratio e_u e_v e_uv ssim normal_angle_deg e_norm_deg e_dist_cm jitter_m spectrum outputs heatmap
check "eval self: 7 frames" grep -q '"frames":7,' "$tmp/self.json"
check "eval self: zero errors" python3 -c "
import json, sys
m = json.load(open('$tmp/self.json'))['metrics']
for k in ['med_m', 'e_dist_cm', 'cd_m2', 'chamfer_m', 'be_rad', 'bed_rad', 'normal_angle_deg', 'e_norm_deg']:
    assert m[k]['max'] == 0, (k, m[k])
assert abs(m['ssim']['min'] - 1) < 1e-9, m['ssim']
assert m['col_m']['mean'] is None and m['pe_rad']['count'] == 0
assert m['ie_j']['count'] == 5 and m['ste_j']['max'] > 0
"
check "eval outputs" test -s "$tmp/self/frames.jsonl" -a -s "$tmp/self/summary.json" \
  -a -s "$tmp/self/heatmap.png" -a -s "$tmp/self/plots/med_m.png" -a -s "$tmp/self/plots/ssim.png"
check "eval frames.jsonl: 7 lines" bash -c "[[ \$(wc -l < '$tmp/self/frames.jsonl') -eq 7 ]]"
check "eval frames.jsonl fields" json_has "$tmp/self/frames.jsonl" frame med_m bed_rad ssim ie_j
check "eval heatmap png" bash -c "head -c 4 '$tmp/self/heatmap.png' | grep -q PNG"
check "eval summary.json = stdout metrics" python3 -c "
import json
a = json.load(open('$tmp/self/summary.json')); b = json.load(open('$tmp/self.json'))
assert a['metrics'] == b['metrics']
"

# the energies are the simulator's own kernels: they match its per-frame log (sample t is
# the state after frame t - 1; PC2 stores float32, so 1e-3 relative)
check "eval energies = simulate's" python3 -c "
import json
e = [json.loads(l) for l in open('$tmp/self/frames.jsonl')]
s = [json.loads(l) for l in open('$tmp/sim/frames.jsonl')]
H = json.load(open('$tmp/self.json'))['hinges']
close = lambda a, b: abs(a - b) <= 1e-3 * abs(b) + 1e-12
for t in range(2, 7):
    assert close(e[t]['ste_j'] + e[t]['she_j'], s[t - 1]['membrane']), t
    assert close(e[t]['ben_j'] * H, s[t - 1]['bending']), t
    assert close(e[t]['ge_j'], s[t - 1]['gravity']), t
    assert close(e[t]['ie_j'], s[t - 1]['inertia']), t
"

# --- a rigid translation by 5 cm: MED = 0.05 m, E_dist 5 cm, normals unchanged -------------
check "eval translated" bash -c "'$crease' eval --pred '$tmp/moved.pc2' --ref '$tmp/sim/sim.pc2' \
  --garment '$tmp/cloth.obj' --body-mesh '$tmp/sphere.obj' -o '$tmp/moved' --json \
  > '$tmp/moved.json' 2>/dev/null"
check "eval translated: MED = d" python3 -c "
import json
m = json.load(open('$tmp/moved.json'))['metrics']
assert abs(m['med_m']['mean'] - 0.05) < 1e-6 and abs(m['med_m']['max'] - 0.05) < 1e-6, m['med_m']
assert abs(m['e_dist_cm']['mean'] - 5) < 1e-4
assert m['normal_angle_deg']['max'] < 0.01 and m['e_norm_deg']['max'] < 0.01, m['e_norm_deg']
assert m['be_rad']['max'] < 1e-4 and m['ssim']['min'] > 0.99999
assert m['col_m']['count'] == 7 and m['collision_ratio']['max'] < 0.05
"
check "eval translated: vertex_error.npy (T,V) of 5 cm" python3 -c "
import json, struct
d = json.load(open('$tmp/moved.json'))
b = open(d['outputs']['vertex_error'], 'rb').read()
n = struct.unpack('<H', b[8:10])[0]
head = b[10:10 + n].decode()
assert \"'descr': '<f4'\" in head and '(%d, %d)' % (d['frames'], d['vertices']) in head, head
v = struct.unpack('<%df' % (d['frames'] * d['vertices']), b[10 + n:])
assert all(abs(x - 0.05) < 1e-6 for x in v), (min(v), max(v))
"

# --- simulate --plastic records its rest angles; eval selects BED hinges by them -------------
check "simulate --plastic writes rest_angles.npy" bash -c "'$crease' simulate --garment '$tmp/cloth.obj' \
  --garment-offset 0,0.35,0 --object sphere --frames 6 --plastic --material silk -o '$tmp/plastic' \
  --quiet --json > '$tmp/plastic.json' 2>/dev/null"
check "rest_angles.npy is (frames + 1, hinges) float32" python3 -c "
import json, struct
d = json.load(open('$tmp/plastic.json'))
b = open(d['outputs']['rest_angles'], 'rb').read()
n = struct.unpack('<H', b[8:10])[0]
head = b[10:10 + n].decode()
assert \"'descr': '<f4'\" in head and '(7, ' in head, head
"
check "eval --rest-angles from simulate" bash -c "'$crease' eval --pred '$tmp/plastic/sim.pc2' \
  --ref '$tmp/plastic/sim.pc2' --garment '$tmp/cloth.obj' --rest-angles '$tmp/plastic/rest_angles.npy' \
  --pred-rest-angles '$tmp/plastic/rest_angles.npy' -o '$tmp/plastic_eval' --json 2>/dev/null \
  | python3 -c \"import json, sys; d = json.load(sys.stdin); assert d['bed_from_rest'] and d['metrics']['pe_rad']['max'] == 0, d['metrics']['pe_rad']\""

# --- the twin, seeds, a baseline: the table ---------------------------------------------------
check "simulate --twin" bash -c "'$crease' simulate --garment '$tmp/cloth.obj' --garment-offset 0,0.35,0 \
  --object sphere --frames 6 --twin -o '$tmp/twin' --quiet --json > '$tmp/twin.json' 2>/dev/null"
check "simulate --twin: the start moved 0.1 mm" python3 -c "
import json, struct
d = json.load(open('$tmp/twin.json'))
assert d['twin']['offset_m'][2] > 0.99e-4 and d['twin']['friction_delta'] == 0, d['twin']
r = open('$tmp/sim/sim.pc2', 'rb').read()[32:]; t = open('$tmp/twin/sim.pc2', 'rb').read()[32:]
n = 144 * 3
a = struct.unpack('<%df' % n, r[:4 * n]); b = struct.unpack('<%df' % n, t[:4 * n])
assert all(abs(b[i] - a[i] - (1e-4 if i % 3 == 2 else 0)) < 1e-6 for i in range(n))
"
check "simulate --friction-delta" bash -c "'$crease' simulate --garment '$tmp/cloth.obj' \
  --garment-offset 0,0.35,0 --object sphere --frames 2 --friction-delta 0.01 -o '$tmp/twin_f' \
  --quiet --json | grep -q '\"friction_delta\":0.01'"
check "eval --twin --baseline, two seeds" bash -c "'$crease' eval --pred '$tmp/twin/sim.pc2,$tmp/sim/sim.pc2' \
  --ref '$tmp/sim/sim.pc2' --twin '$tmp/twin/sim.pc2' --baseline '$tmp/moved.pc2' \
  --garment '$tmp/cloth.obj' --body-mesh '$tmp/sphere.obj' -o '$tmp/table' --json \
  > '$tmp/table.json' 2> '$tmp/table.err'"
check "eval fold measures" json_has "$tmp/table.json" bed_ring_rad pe_ring_rad bed_sorted_rad \
  pe_sorted_rad pe_rb0_rad pe_ring_rb0_rad fold_share fold_share_ref band_power resolved \
  mean_edge_m folds retention_pred retention_ref hem amplitude_pred_m frequency_ref_hz table seeds \
  twin baseline removed twin_removed
check "eval table: rows and files" bash -c "grep -q '| prediction (2 seeds) |' '$tmp/table.err' && \
  grep -q '^| twin |' '$tmp/table/table.md' && grep -q '^| baseline |' '$tmp/table/table.md' && \
  test -s '$tmp/table/twin/summary.json' -a -s '$tmp/table/baseline/summary.json' \
  -a -s '$tmp/table/seed2/summary.json' -a -s '$tmp/table/table.json'"
check "eval table: the figures" python3 -c "
import json
d = json.load(open('$tmp/table.json'))
t = d['table']
assert t['seeds']['n'] == 2
med = t['seeds']['metrics']['med_m']
assert 0 < med['mean'] < 0.01 and med['spread'] > 0, med        # the twin's and 0
assert abs(t['baseline']['med_m'] - 0.05) < 1e-6                  # the 5 cm translation
# the share removed is 1 - error / the baseline's, the seeds' the mean of the two (the twin's and
# the reference's own 1); the twin's own error is chaos (a coarse cloth hitting the sphere), so
# only its size is bounded
tw = t['twin']['med_m']
assert 0 < tw < 0.01 and abs(t['twin_removed']['med_m'] - (1 - tw / 0.05)) < 1e-6, t['twin']
assert abs(t['removed']['med_m']['mean'] - (1 + t['twin_removed']['med_m']) / 2) < 1e-6
assert d['metrics']['bed_ring_rad']['max'] <= d['metrics']['bed_rad']['max'] + 1e-12
"
check "eval --help lists every fold option" bash -c "'$crease' eval --help | grep -q -- --twin-rest-angles \
  && '$crease' eval --help | grep -q -- --resolve-edges && '$crease' eval --help | grep -q -- --ring"
check "docs/cli.md lists every eval option" bash -c "for o in \$('$crease' eval --help | grep -o -- \
  '--[a-z][a-z-]*' | sort -u); do grep -q -- \"\$o\" '$(dirname "$0")/../docs/cli.md' || \
  { echo \"docs/cli.md misses eval \$o\"; exit 1; }; done"
expect_exit 2 "one per prediction" eval --pred "$tmp/sim/sim.pc2,$tmp/twin/sim.pc2" \
  --pred-rest-angles "$tmp/plastic/rest_angles.npy,$tmp/plastic/rest_angles.npy,$tmp/plastic/rest_angles.npy" \
  --ref "$tmp/sim/sim.pc2" --garment "$tmp/cloth.obj" -o "$tmp/x"
expect_exit 2 "--twin-rest-angles needs --twin" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" \
  --twin-rest-angles "$tmp/plastic/rest_angles.npy" --garment "$tmp/cloth.obj" -o "$tmp/x"

# --- bad input: exit 1 naming the files; usage: exit 2 --------------------------------------
expect_exit 1 "sim10/sim.pc2.*sim/sim.pc2|sim/sim.pc2.*sim10/sim.pc2" eval --pred "$tmp/sim10/sim.pc2" \
  --ref "$tmp/sim/sim.pc2" --garment "$tmp/cloth.obj" -o "$tmp/x"
expect_exit 1 "sim3/sim.pc2.*4 frames.*sim/sim.pc2.*7" eval --pred "$tmp/sim3/sim.pc2" \
  --ref "$tmp/sim/sim.pc2" --garment "$tmp/cloth.obj" -o "$tmp/x"
expect_exit 1 "cloth10.obj.*100.*144" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" \
  --garment "$tmp/cloth10.obj" -o "$tmp/x"
# a rest garment or a sequence in centimetres: refused, naming both files and sizes
"$crease" primitive plane --res 12 --size 100 -o "$tmp/cloth_cm.obj" >/dev/null
expect_exit 1 "cloth_cm.obj is 141.4 m across.*frame 0 of .*sim/sim.pc2 is [0-9.]+ m.*metres" eval \
  --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" --garment "$tmp/cloth_cm.obj" -o "$tmp/x"
expect_exit 1 "cloth.obj is 1.414 m across.*frame 0 of .*cm.pc2 is [0-9.]+ m, more than 5 times larger" \
  eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/cm.pc2" --garment "$tmp/cloth.obj" -o "$tmp/x"
expect_exit 1 "nan.pc2" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/nan.pc2" --garment "$tmp/cloth.obj" \
  -o "$tmp/x"
expect_exit 1 "nope.pc2" eval --pred "$tmp/nope.pc2" --ref "$tmp/sim/sim.pc2" --garment "$tmp/cloth.obj" \
  -o "$tmp/x"
expect_exit 1 "nope.obj" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" --garment "$tmp/nope.obj" \
  -o "$tmp/x"
expect_exit 1 "sim.pc2.*144.*sphere.obj" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" \
  --garment "$tmp/cloth.obj" --body "$tmp/sim/sim.pc2" --body-mesh "$tmp/sphere.obj" -o "$tmp/x"
expect_exit 2 "-o DIR" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" --garment "$tmp/cloth.obj"
expect_exit 2 "--ref" eval --pred "$tmp/sim/sim.pc2" --garment "$tmp/cloth.obj" -o "$tmp/x"
expect_exit 2 "--body-mesh" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" \
  --garment "$tmp/cloth.obj" --body "$tmp/sim/sim.pc2" -o "$tmp/x"
expect_exit 2 "--fps" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" \
  --garment "$tmp/cloth.obj" --fps 0 -o "$tmp/x"
expect_exit 2 "velvet" eval --pred "$tmp/sim/sim.pc2" --ref "$tmp/sim/sim.pc2" \
  --garment "$tmp/cloth.obj" --material velvet -o "$tmp/x"

echo "cli_eval: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
