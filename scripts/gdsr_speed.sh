#!/usr/bin/env bash
# gdsr_speed.sh: issue 19's speed figure in one run, on one machine under one load: seconds
# per frame of the low-resolution simulation, of the high-resolution simulation of the same
# frames, and of gdsr super-resolving the low one (collision handling included). The
# simulations' figure is the mean of frames.jsonl's per-step "seconds" (the settle and the
# set-up left out); gdsr's is `gdsr run`'s seconds_per_frame (wall) and
# cpu_seconds_per_frame (from its second frame through the networks: the first also pays the
# one-time warm-up, reported apart as gdsr_first_frame_s, as the simulators' set-up is).
# Goal: high / (low + gdsr) >= 5. Prints one JSON line.
# Usage: gdsr_speed.sh PATH_TO_CREASE MODEL.safetensors [FRAMES (10)] [OUT_DIR (a temp one)]
#        [LOW_VERTICES (500)] [HIGH_VERTICES (4000)]
# The cost of a frame does not depend on the weights, so a model trained at other sizes times
# the same as one trained at these (the graph net and the hyper-net work on any mesh).
set -euo pipefail
crease=$1 model=$2 frames=${3:-10} out=${4:-} low_v=${5:-500} high_v=${6:-4000}
if [[ -z $out ]]; then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
"$crease" dataset --garments tshirt --motions walk --res low,high --low-vertices "$low_v" \
  --high-vertices "$high_v" --frames "$frames" --quiet -o "$out/data" >/dev/null
"$crease" gdsr run --dataset "$out/data" --motion walk --model "$model" --quiet \
  -o "$out/run" --json >"$out/run.json"
python3 - "$out" "$(uptime)" <<'PY'
import json, sys
out, up = sys.argv[1], sys.argv[2]
def per_frame(res):
    rows = [json.loads(l) for l in open(f"{out}/data/sequences/tshirt_{res}_normal_walk/frames.jsonl")]
    return sum(r["seconds"] for r in rows) / len(rows), len(rows)
low, n = per_frame("low")
high, _ = per_frame("high")
run = json.load(open(f"{out}/run.json"))
g, gc = run["seconds_per_frame"], run["cpu_seconds_per_frame"]
print(json.dumps({"frames": n, "low_vertices": run["low_vertices"],
                  "high_vertices": run["high_vertices"], "low_sim_s": round(low, 4),
                  "high_sim_s": round(high, 4), "gdsr_s": round(g, 4), "gdsr_cpu_s": round(gc, 4),
                  "gdsr_first_frame_s": round(run["first_frame_seconds"], 4),
                  "gdsr_stages_s": {k: round(v, 4) for k, v in run["stage_seconds_per_frame"].items()},
                  "speedup": round(high / (low + g), 2), "load": up.split("load average:")[-1].strip()}))
PY
