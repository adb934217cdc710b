#!/usr/bin/env bash
# runtime.sh: the methods' frame-by-frame runtimes from outside the tool. examples/runtime_loop.c
# streams a CMU-style BVH through SwinGar's and EPNet's into animated glbs, and through a low
# simulation and gdsr's. python/crease.py drives SwinGar's runtime frame by frame through ctypes and
# numpy, and gives what `crease swingar run --raw` writes for the same model, garment and clip (the
# batch tool goes through the same runtime): within 1e-5 m on every frame. Also: a batch of two
# characters equals each alone, reset starts over, a missing model raises crease.Error naming
# the file, a wrong pose shape is refused. gdsr's runtime, stepped from Python over a dataset's
# low simulation and posed body, gives `gdsr run`'s gdsr.pc2 and gdsr_raw.pc2 within 1e-5 m, one
# character or two in a batch call. Debian's python3 with python3-numpy (scripts/deps.sh).
# Usage: runtime.sh PATH_TO_CREASE PATH_TO_LIBCREASE_RUNTIME_SO (the examples beside the tool)
source "$(dirname "$0")/lib_cli.sh" "$1"
export CREASE_LIBRARY=${2:?usage: runtime.sh CREASE LIBCREASE_RUNTIME_SO}
export OPENBLAS_NUM_THREADS=1 OMP_WAIT_POLICY=passive
src=$(cd "$(dirname "$0")/.." && pwd)
# Debian's interpreter, whose numpy scripts/deps.sh installs (a python3 earlier on PATH, such
# as a pyenv one, may have none)
py=/usr/bin/python3
[[ -x $py ]] || py=$(command -v python3)

check "dataset" "$crease" dataset --garments dress --motions walk --low-vertices 500 --frames 8 \
  -o "$tmp/data" --quiet
check "train" "$crease" swingar train --dataset "$tmp/data" --size tiny --epochs 2 --window 4 \
  --batch 2 --lr 1e-2 -o "$tmp/m.safetensors" --quiet
g=$(find "$tmp/data/garments" -name '*.obj' | head -n 1)
check "motion" "$crease" motion --clip walk --frames 20 -o "$tmp/walk.npz"
check "run" "$crease" swingar run --model "$tmp/m.safetensors" --garment "$g" --motion walk \
  --frames 20 --raw -o "$tmp/run"
# the C example, on a BVH laid out as the CMU database's (example_cmu_walk_bvh)
bin=$(dirname "$crease")
check "bvh" "$bin/example_cmu_walk_bvh" "$tmp/walk.bvh" 1
check "runtime_loop swingar" bash -c "'$bin/example_runtime_loop' swingar '$tmp/m.safetensors' '$g' \
  '$tmp/walk.bvh' '$tmp/loop.glb' > '$tmp/loop.out'"
check "epnet train" "$crease" epnet train --vertices 500 --motions squat --frames 12 --epochs 2 \
  --pnet-epochs 1 --yield 0.1 --cycles 1 -o "$tmp/ep"
check "runtime_loop epnet" bash -c "'$bin/example_runtime_loop' epnet '$tmp/ep' '$tmp/walk.bvh' \
  '$tmp/loop_ep.glb' >> '$tmp/loop.out'"
check "runtime_loop glbs" bash -c "[[ \$(head -c 4 '$tmp/loop.glb') == glTF && \$(head -c 4 '$tmp/loop_ep.glb') == glTF ]] && [[ \$(grep -c 'frames/s' '$tmp/loop.out') == 2 ]]"
cat "$tmp/loop.out"
check "epnet run" "$crease" epnet run --model "$tmp/ep" --motion squat --frames 12 -o "$tmp/eprun"
check "epnet motion" "$crease" motion --clip squat --frames 12 --fps "$(grep -o '"fps": *[0-9.]*' "$tmp/ep/model.json" | grep -o '[0-9.]*$')" -o "$tmp/squat.npz"
check "gdsr dataset" "$crease" dataset --garments tshirt --motions walk --res low,high \
  --low-vertices 500 --high-vertices 1000 --frames 6 --quiet -o "$tmp/gdata"
check "gdsr train" "$crease" gdsr train --dataset "$tmp/gdata" --motions walk --latent 16 --steps 1 \
  --epochs 1 --quiet -o "$tmp/gm"
check "gdsr run" "$crease" gdsr run --dataset "$tmp/gdata" --motion walk \
  --model "$tmp/gm/model.safetensors" --quiet -o "$tmp/grun"
check "runtime_loop gdsr" bash -c "'$bin/example_runtime_loop' gdsr '$tmp/gm/model.safetensors' \
  '$tmp/gdata' '$tmp/walk.bvh' '$tmp/loop_gd.glb' > '$tmp/loop_gd.out' && [[ \$(head -c 4 '$tmp/loop_gd.glb') == glTF ]]"
cat "$tmp/loop_gd.out"
if PYTHONPATH=$src/python "$py" - "$tmp" "$g" >"$tmp/py.out" 2>&1 <<'EOF_PY'
import json
import sys
import numpy as np
import crease

tmp, garment = sys.argv[1], sys.argv[2]
mo = np.load(tmp + "/walk.npz")
poses, trans = mo["poses"].reshape(-1, 22, 3), mo["trans"]
with open(tmp + "/run/garment.pc2", "rb") as f:
    head = f.read(32)
    assert head[:12] == b"POINTCACHE2\0", head[:12]
    nv, nframes = np.frombuffer(head[16:20], "<i4")[0], np.frombuffer(head[28:32], "<i4")[0]
    ref = np.frombuffer(f.read(), "<f4").reshape(nframes, nv, 3)
assert ref.shape[0] == len(poses), (ref.shape, poses.shape)
with crease.SwingarRuntime(tmp + "/m.safetensors", garment, body="normal") as rt:
    assert rt.vertices == nv and rt.triangles.shape[1] == 3 and rt.triangles.max() < nv
    out = np.empty((rt.vertices, 3), np.float32)
    d = max(np.abs(rt.step(p, r, out=out) - ref[t]).max() for t, (p, r) in enumerate(zip(poses, trans)))
    print("runtime vs swingar run: max %.2e m over %d frames, %d vertices, arena %d bytes"
          % (d, len(poses), nv, rt.arena_bytes))
    assert d < 1e-5, d
    rt.reset()
    with crease.SwingarRuntime(tmp + "/m.safetensors", garment) as rt2:
        db = 0.0
        for t in range(len(poses)):
            a, b = crease.SwingarRuntime.step_batch([rt, rt2], poses[[t, t]], trans[[t, t]])
            db = max(db, np.abs(a - ref[t]).max(), np.abs(b - ref[t]).max())
        print("batch of two after a reset: max %.2e m" % db)
        assert db < 1e-5, db
    try:
        rt.step(np.zeros(5), np.zeros(3))
        raise AssertionError("a (5,) pose was accepted")
    except crease.Error as e:
        print("wrong pose:", e)
try:
    crease.SwingarRuntime(tmp + "/no_such_model.safetensors", garment)
    raise AssertionError("a missing model opened")
except crease.Error as e:
    print("missing model:", e)
    assert "no_such_model" in str(e)
mo = np.load(tmp + "/squat.npz")
with open(tmp + "/eprun/garment.pc2", "rb") as f:
    head = f.read(32)
    nv, nframes = np.frombuffer(head[16:20], "<i4")[0], np.frombuffer(head[28:32], "<i4")[0]
    ref = np.frombuffer(f.read(), "<f4").reshape(nframes, nv, 3)
with crease.EpnetRuntime(tmp + "/ep") as ep:
    d = max(np.abs(ep.step(p, r) - ref[t]).max()
            for t, (p, r) in enumerate(zip(mo["poses"].reshape(-1, 22, 3), mo["trans"])))
    print("epnet runtime vs epnet run: max %.2e m over %d frames, %d vertices, max |RB| %.3f rad"
          % (d, nframes, nv, np.abs(ep.rb()).max()))
    assert d < 1e-5, d


def pc2(path):
    with open(path, "rb") as f:
        head = f.read(32)
        nv, nframes = np.frombuffer(head[16:20], "<i4")[0], np.frombuffer(head[28:32], "<i4")[0]
        return np.frombuffer(f.read(), "<f4").reshape(nframes, nv, 3)


man = json.load(open(tmp + "/gdata/manifest.json"))
seq = [q for q in man["sequences"] if q["res"] == "low" and q["motion"] == "walk"][0]
low = pc2(tmp + "/gdata/" + seq["garment_pc2"])
body = pc2(tmp + "/grun/body.pc2")
ref, ref_raw = pc2(tmp + "/grun/gdsr.pc2"), pc2(tmp + "/grun/gdsr_raw.pc2")
with crease.GdsrRuntime(tmp + "/gm/model.safetensors", tmp + "/gdata") as gd, \
        crease.GdsrRuntime(tmp + "/gm/model.safetensors", tmp + "/gdata") as gd2:
    assert gd.vertices == ref.shape[1] and gd.low_vertices == low.shape[1]
    d = dr = db = 0.0
    for t in range(len(low)):
        d = max(d, np.abs(gd.step(low[t], body[t]) - ref[t]).max())
        dr = max(dr, np.abs(gd.raw() - ref_raw[t]).max())
    gd.reset()
    for t in range(len(low)):
        a, b = crease.GdsrRuntime.step_batch([gd, gd2], [low[t]] * 2, [body[t]] * 2)
        db = max(db, np.abs(a - ref[t]).max(), np.abs(b - ref[t]).max())
    print("gdsr runtime vs gdsr run: max %.2e m (raw %.2e m, a batch of two after a reset "
          "%.2e m) over %d frames, %d -> %d vertices, arena %d bytes"
          % (d, dr, db, len(low), gd.low_vertices, gd.vertices, gd.arena_bytes))
    assert d < 1e-5 and dr < 1e-5 and db < 1e-5, (d, dr, db)
print("ok")
EOF_PY
then
  passed=$((passed + 1))
  cat "$tmp/py.out"
else
  failed=$((failed + 1))
  echo "FAIL: python/crease.py:" >&2
  cat "$tmp/py.out" >&2
fi
echo "runtime: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
