#!/usr/bin/env bash
# blender_glb.sh: Blender imports crease's skinned, animated mannequin (crease pose-body -o X.glb)
# as an armature with its 22 bones, a skinned mesh and an action, and the armature moves: the
# left knee's head at two frames half a second apart differs. Skips (77) without Blender, which
# is not one of crease's dependencies (Debian's blender package: 3.4; its glTF importer needs
# numpy's old np.bool alias, restored in the script).
# Usage: blender_glb.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"
command -v blender >/dev/null || { echo "blender_glb: no blender, skipped"; exit 77; }
check "pose-body" "$crease" pose-body --motion walk --frames 30 -o "$tmp/walk.glb"
cat >"$tmp/import.py" <<'EOF_PY'
import sys
import numpy
if not hasattr(numpy, "bool"):
    numpy.bool = bool  # Debian's Blender 3.4 glTF importer with numpy >= 1.24
import bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=sys.argv[-1])
arm = [o for o in bpy.data.objects if o.type == "ARMATURE"]
mesh = [o for o in bpy.data.objects if o.type == "MESH"]
assert len(arm) == 1 and len(mesh) == 1, (arm, mesh)
assert mesh[0].find_armature() == arm[0], "the mesh is not skinned to the armature"
assert len(arm[0].pose.bones) == 22, len(arm[0].pose.bones)
action = arm[0].animation_data.action
f0, f1 = action.frame_range
print("action %s, frames %g..%g" % (action.name, f0, f1))
knee = arm[0].pose.bones["left_knee"]
heads = []
for f in (f0, f0 + 15):
    bpy.context.scene.frame_set(int(f))
    heads.append((arm[0].matrix_world @ knee.matrix).translation.copy())
    print("frame %d: left_knee head %s" % (f, tuple(round(x, 4) for x in heads[-1])))
moved = (heads[1] - heads[0]).length
print("left knee moved %.3f m" % moved)
assert moved > 0.05, moved
print("BLENDER_OK")
EOF_PY
if timeout 300 blender -b --python "$tmp/import.py" -- "$tmp/walk.glb" >"$tmp/blender.log" 2>&1 &&
  grep -q BLENDER_OK "$tmp/blender.log"; then
  passed=$((passed + 1))
  grep -E "^(action|frame|left knee)" "$tmp/blender.log"
else
  failed=$((failed + 1))
  echo "FAIL: blender import:" >&2
  tail -20 "$tmp/blender.log" >&2
fi
echo "blender_glb: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
