#!/usr/bin/env bash
# depth_row.sh CREASE OUT RUN KEY GARMENT SHOT: one row of your_garment.sh's and
# your_character.sh's tables, for the run OUT/RUN_KEY (RUN: sim, epnet_run or swingar_run;
# KEY: the body or the motion). The body is OUT/sim_KEY's (body.obj; body.pc2 for the
# simulation, whose frame t is body sample t from the rest pose) or OUT/swingar_run_KEY's
# body.pc2 (epnet and swingar run the motion from its first frame, and swingar writes that
# body). `crease eval` of the garment's frames against it (in RUN_KEY/eval), the deepest vertex
# and face centroid inside the body after the first second (frames 30 on), the collar's drop
# (the first frame's highest garment vertex, its fall from the first frame to the last
# relative to the body's skin point nearest it at the first: a garment sliding off falls,
# a body moving up or down does not count), and frame SHOT rendered to RUN_KEY/frameSHOT.png. Prints "| KEY | method | vertex mm | face
# mm | drop mm | picture |".
set -euo pipefail
crease=$1 out=$2 run=$3 key=$4 g=$5 shot=$6
d="$out/${run}_$key"
bm="$out/sim_$key/body.obj"
bp="$out/swingar_run_$key/body.pc2"
[[ $run == sim ]] && bp="$out/sim_$key/body.pc2"
pc2="$d/garment.pc2"
[[ -e "$d/sim.pc2" ]] && pc2="$d/sim.pc2"
"$crease" eval --pred "$pc2" --ref "$pc2" --garment "$g" --body "$bp" --body-mesh "$bm" \
  -o "$d/eval" >/dev/null 2>&1
"$crease" render "$g" --pc2 "$pc2" "$bm" --pc2 "$bp" --frame "$shot" --size 640 \
  -o "$d/frame$shot.png" >/dev/null
/usr/bin/python3 - "$d/eval/frames.jsonl" "$pc2" "$key" "${run%_run}" "$d/frame$shot.png" "$bp" \
  <<'PY'
import json, sys
import numpy as np
rows = [json.loads(l) for l in open(sys.argv[1])]
late = [r for r in rows if r["frame"] >= 30]
v = max(r["col_max_m"] or 0 for r in late) * 1e3
f = max(r["col_face_max_m"] or 0 for r in late) * 1e3
def pc2(path):
    raw = open(path, "rb").read()
    n, t = np.frombuffer(raw[16:20], "<i4")[0], np.frombuffer(raw[28:32], "<i4")[0]
    return np.frombuffer(raw[32:], "<f4").reshape(t, n, 3)
x, b = pc2(sys.argv[2]), pc2(sys.argv[6])
last = min(len(x), len(b)) - 1
top = x[0, :, 1].argmax()  # the collar, followed against the skin point nearest it at frame 0
skin = np.linalg.norm(b[0] - x[0, top], axis=1).argmin()
drop = ((x[0, top, 1] - b[0, skin, 1]) - (x[last, top, 1] - b[last, skin, 1])) * 1e3
print(f"| {sys.argv[3]} | {sys.argv[4]} | {v:.2f} | {f:.2f} | {drop:.1f} | {sys.argv[5]} |")
PY
