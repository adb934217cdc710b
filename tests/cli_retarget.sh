#!/usr/bin/env bash
# cli_retarget.sh: `crease simulate --body-mesh CHAR.glb --motion F.bvh`: a garment simulated
# for a few frames on a rigged character with Mixamo joint names (crease's mannequin written by
# pose-body, its joints renamed) driven by a CMU-named BVH retargeted onto its skeleton; a joint
# map file for names no table knows; the character, with other proportions, as the body
# epnet trains and runs on; refusals name the file and what is missing.
source "$(dirname "$0")/lib_cli.sh" "$1"

json_num() { # json_num FILE KEY: the number at KEY in the last line
  tail -n 1 "$1" | grep -o "\"$2\":[-0-9.eE+]*" | head -n 1 | cut -d: -f2
}
json_between() { # json_between FILE KEY LO HI: LO <= number at KEY <= HI
  local v; v=$(json_num "$1" "$2")
  [[ -n $v ]] && awk -v v="$v" -v lo="$3" -v hi="$4" 'BEGIN { exit !(v >= lo && v <= hi) }'
}

check "garment" "$crease" garment --type tshirt --res 800 --body-res 72 -o "$tmp/t.obj"
check "mannequin glb" "$crease" pose-body --clip walk --frames 2 --res 72 -o "$tmp/m.glb"
# the skin's joints renamed (SMPL's names -> Mixamo's, or boneNN)
mk="$(dirname "$0")/make_character.py"
check "mixamo character" python3 "$mk" "$tmp/m.glb" "$tmp/char.glb" mixamo
check "boneNN character" python3 "$mk" "$tmp/m.glb" "$tmp/bones.glb" bones
# a CMU-named rig in a T-pose, centimetres: 12 frames at 30 fps, the arms brought down and
# swinging, the legs stepping
cat > "$tmp/bvh.py" <<'PY'
import math, sys
J = [("Hips", -1, (0, 95, 0)), ("LHipJoint", 0, (5, -5, 0)), ("LeftUpLeg", 1, (4, -5, 0)),
     ("LeftLeg", 2, (0, -42, 0)), ("LeftFoot", 3, (0, -40, 0)), ("LeftToeBase", 4, (0, -6, 12)),
     ("RHipJoint", 0, (-5, -5, 0)), ("RightUpLeg", 6, (-4, -5, 0)), ("RightLeg", 7, (0, -42, 0)),
     ("RightFoot", 8, (0, -40, 0)), ("RightToeBase", 9, (0, -6, 12)), ("LowerBack", 0, (0, 6, 0)),
     ("Spine", 11, (0, 10, 0)), ("Spine1", 12, (0, 10, 0)), ("Neck", 13, (0, 15, 0)),
     ("Head", 14, (0, 10, 0)), ("LeftShoulder", 13, (3, 12, 0)), ("LeftArm", 16, (15, 0, 0)),
     ("LeftForeArm", 17, (28, 0, 0)), ("LeftHand", 18, (25, 0, 0)),
     ("RightShoulder", 13, (-3, 12, 0)), ("RightArm", 20, (-15, 0, 0)),
     ("RightForeArm", 21, (-28, 0, 0)), ("RightHand", 22, (-25, 0, 0))]
order = []
def dfs(i):
    order.append(i)
    for c, (_, p, _) in enumerate(J):
        if p == i: dfs(c)
dfs(0)
out, stack = ["HIERARCHY"], []
for i in order:
    name, p, off = J[i]
    while stack and stack[-1] != p:
        out.append("}"); stack.pop()
    out.append(("ROOT " if p < 0 else "JOINT ") + name)
    out.append("{")
    out.append("OFFSET %g %g %g" % off)
    out.append("CHANNELS " + ("6 Xposition Yposition Zposition" if p < 0 else "3") +
               " Zrotation Xrotation Yrotation")
    stack.append(i)
out += ["}"] * len(stack)
T = 12
out += ["MOTION", "Frames: %d" % T, "Frame Time: 0.0333333"]
for f in range(T):
    s = math.sin(0.5 * f)
    ang = {2: (0, 20 * s, 0), 7: (0, -20 * s, 0), 3: (0, 20 + 15 * s, 0), 8: (0, 20 - 15 * s, 0),
           17: (-60, 10 * s, 0), 21: (60, -10 * s, 0)}
    row = [0.0, 95.0, 1.0 * f]
    for i in order:
        row += ang.get(i, (0, 0, 0))
    out.append(" ".join("%g" % v for v in row))
open(sys.argv[1], "w").write("\n".join(out) + "\n")
PY
check "bvh" python3 "$tmp/bvh.py" "$tmp/walk.bvh"

# --- the Mixamo-named character driven by the BVH -------------------------------------------
check "simulate on the retargeted character" bash -c "'$crease' simulate --garment '$tmp/t.obj' \
  --body-mesh '$tmp/char.glb' --motion '$tmp/walk.bvh' --ease-in 0.2 --frames 4 \
  -o '$tmp/sim' --quiet --json > '$tmp/sim.json' 2> '$tmp/sim.err'"
check "4 frames, not diverged" grep -q '"frames":4,"frames_requested":4,"diverged":false' \
  "$tmp/sim.json"
check "garment stays outside" json_between "$tmp/sim.json" max_penetration_m 0 0.005
check "names matched" grep -q "Mixamo joint names, 22 of 22" "$tmp/sim.err"
check "scene.glb: the character and the garment" bash -c "head -c 20000 '$tmp/sim/scene.glb' | \
  grep -aq 'mixamorig:LeftArm' && head -c 20000 '$tmp/sim/scene.glb' | grep -aq '\"garment\"'"

# --- a range of the BVH's frames: 6 of its 12, eased into over 0.2 s ----------------------------
check "simulate frames 4..9" bash -c "'$crease' simulate --garment '$tmp/t.obj' \
  --body-mesh '$tmp/char.glb' --motion '$tmp/walk.bvh' --start-frame 4 --end-frame 9 \
  --ease-in 0.2 --frames 14 -o '$tmp/sim_range' --quiet 2> '$tmp/range.err'"
check "the range's frames and the ease-in only" grep -q "walk.bvh: 12 frames (with the ease-in) for 14" \
  "$tmp/range.err"
expect_exit 1 "walk.bvh: frames 4..12 asked for, the file has 0..11" simulate \
  --garment "$tmp/t.obj" --body-mesh "$tmp/char.glb" --motion "$tmp/walk.bvh" --start-frame 4 \
  --end-frame 12 --frames 1 -o "$tmp/x"

# --- a joint map file for names no table knows ----------------------------------------------
expect_exit 1 "bones.glb: no joint of the character is mapped to the hips" simulate \
  --garment "$tmp/t.obj" --body-mesh "$tmp/bones.glb" --motion "$tmp/walk.bvh" --frames 1 \
  -o "$tmp/x"
python3 - "$tmp/map.txt" <<'PY'
import sys
cmu = ["Hips", "LeftUpLeg", "RightUpLeg", "LowerBack", "LeftLeg", "RightLeg", "Spine",
       "LeftFoot", "RightFoot", "Spine1", "LeftToeBase", "RightToeBase", "Neck",
       "LeftShoulder", "RightShoulder", "Head", "LeftArm", "RightArm", "LeftForeArm",
       "RightForeArm", "LeftHand", "RightHand"]
open(sys.argv[1], "w").write("# boneNN = CMU joint\n" +
                             "".join("bone%02d = %s\n" % (i, n) for i, n in enumerate(cmu)))
PY
check "simulate with a joint map" "$crease" simulate --garment "$tmp/t.obj" \
  --body-mesh "$tmp/bones.glb" --motion "$tmp/walk.bvh" --joint-map "$tmp/map.txt" \
  --ease-in 0.2 --frames 2 -o "$tmp/sim_map" --quiet
printf 'bone00 = Hips\nbone16 LeftArm\n' > "$tmp/bad.txt"
expect_exit 1 "bad.txt:2: expected 'character_joint = bvh_joint'" simulate --garment "$tmp/t.obj" \
  --body-mesh "$tmp/bones.glb" --motion "$tmp/walk.bvh" --joint-map "$tmp/bad.txt" --frames 1 \
  -o "$tmp/x"
printf 'bone00 = Hips\nbone16 = LeftUpperArm\n' > "$tmp/bad2.txt"
expect_exit 1 "bad2.txt:2: the motion .*walk.bvh has no joint 'LeftUpperArm'" simulate \
  --garment "$tmp/t.obj" --body-mesh "$tmp/bones.glb" --motion "$tmp/walk.bvh" \
  --joint-map "$tmp/bad2.txt" --frames 1 -o "$tmp/x"

# --- the character as the body of a method: longer legs and spine, shorter arms, a T-pose ---
check "proportioned, T-posed character" python3 "$mk" "$tmp/m.glb" "$tmp/prop.glb" mixamo proportions tpose
check "epnet train on it" bash -c "'$crease' epnet train --body '$tmp/prop.glb' --vertices 500 \
  --motions squat --frames 12 --epochs 8 --pnet-epochs 1 --cycles 1 -o '$tmp/ep' \
  2> '$tmp/ep.err'"
check "its 22 joints by name, taller" grep -Eq "prop.glb: [0-9]+ vertices, 22 of 22 body joints found \(Mixamo names\), 1\.(8[5-9]|9)" \
  "$tmp/ep.err"
check "epnet run on it" bash -c "'$crease' epnet run --model '$tmp/ep' --motion walk --frames 30 \
  -o '$tmp/er' --json > '$tmp/er.json' 2> /dev/null"
# the issue's bar: no vertex more than 5 mm inside the body
check "the garment outside the character" json_between "$tmp/er.json" min_body_distance -0.005 1
check "a t-shirt modelled on it" "$crease" garment --type tshirt --res 800 --body "$tmp/prop.glb" \
  -o "$tmp/pt.obj"
check "simulated on it by a clip" bash -c "'$crease' simulate --garment '$tmp/pt.obj' --motion walk \
  --body '$tmp/prop.glb' --frames 8 --ease-in 0.2 -o '$tmp/psim' --quiet --json > '$tmp/psim.json'"
check "not diverged" grep -q '"diverged":false' "$tmp/psim.json"
check "within 5 mm of the skin" json_between "$tmp/psim.json" max_penetration_m 0 0.005
expect_exit 2 "--body replaces the mannequin" garment --type tshirt --body "$tmp/prop.glb" \
  --shape slim -o "$tmp/x.obj"
expect_exit 1 "bones.glb: no joint of the character is mapped to the hips" epnet train \
  --body "$tmp/bones.glb" --cycles 1 -o "$tmp/x"
python3 - "$tmp/smpl_map.txt" <<'PY'
import sys
smpl = ["pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
        "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
        "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
        "left_wrist", "right_wrist"]
open(sys.argv[1], "w").write("".join("bone%02d = %s\n" % (i, n) for i, n in enumerate(smpl)))
PY
check "meaningless names with a map naming SMPL's joints" bash -c "'$crease' epnet train \
  --body '$tmp/bones.glb:$tmp/smpl_map.txt' --vertices 500 --motions squat --frames 12 --epochs 1 \
  --pnet-epochs 1 --cycles 1 -o '$tmp/ep2' 2> '$tmp/ep2.err'"
check "found by the map" grep -q "22 of 22 body joints found (.*, a joint map)" "$tmp/ep2.err"

# --- a character driven by its own animation -------------------------------------------------
# a squat as the file's own animation, under a Blender-style armature (Z-up, centimetres,
# scale 0.01), with a root joint and end joints no body has, other names and proportions, a
# T-pose rest: read back as a motion it is the squat it was written with
check "squatting mannequin glb" "$crease" pose-body --clip squat --frames 12 --res 72 \
  -o "$tmp/squat.glb"
check "animated character" python3 "$mk" "$tmp/squat.glb" "$tmp/own.glb" mixamo proportions \
  tpose animated extra armature
check "its own animation as a motion" bash -c "'$crease' motion --input '$tmp/own.glb' \
  -o '$tmp/own.npz' 2> '$tmp/own.err'"
check "its names" grep -q "own.glb: its own animation, 12 frames at 30 fps; 22 of 22 body joints found (Mixamo names)" \
  "$tmp/own.err"
check "the mannequin's as a motion" "$crease" motion --input "$tmp/squat.glb" -o "$tmp/squat.npz"
check "the same squat" /usr/bin/python3 -c "
import numpy as np, sys
a, b = np.load('$tmp/own.npz'), np.load('$tmp/squat.npz')
sys.exit(not (abs(a['poses'] - b['poses']).max() < 1e-4 and abs(a['trans'] - b['trans']).max() < 1e-4))"
check "a t-shirt modelled on the character" "$crease" garment --type tshirt --res 800 \
  --body "$tmp/own.glb" -o "$tmp/ot.obj"
check "simulated on it by its own animation" bash -c "'$crease' simulate --garment '$tmp/ot.obj' \
  --body '$tmp/own.glb' --motion '$tmp/own.glb' --frames 8 --ease-in 0.2 -o '$tmp/osim' --quiet \
  --json > '$tmp/osim.json'"
check "not diverged" grep -q '"diverged":false' "$tmp/osim.json"
check "within 5 mm of the skin" json_between "$tmp/osim.json" max_penetration_m 0 0.005
check "a joint map names its joints" bash -c "'$crease' motion \
  --input '$tmp/bones.glb:$tmp/smpl_map.txt' -o '$tmp/bones.npz' 2> '$tmp/bones.err'"
check "found by the map" grep -q "bones.glb: its own animation, 2 frames at 30 fps; 22 of 22 body joints found (.*, a joint map)" \
  "$tmp/bones.err"
expect_exit 1 "prop.glb: no animation" motion --input "$tmp/prop.glb" -o "$tmp/x.npz"
# another character's animation onto the Mixamo-named one's own skeleton
check "simulate driven by another character's animation" bash -c "'$crease' simulate \
  --garment '$tmp/t.obj' --body-mesh '$tmp/char.glb' --motion '$tmp/own.glb' --ease-in 0.2 \
  --frames 4 -o '$tmp/sim_other' --quiet --json > '$tmp/other.json' 2> '$tmp/other.err'"
check "driven by it" grep -q "char.glb: Mixamo joint names, 22 of 22 body joints found by name; 22 of 22 joints driven by .*own.glb" \
  "$tmp/other.err"
check "not diverged, outside" json_between "$tmp/other.json" max_penetration_m 0 0.005

# --- refusals --------------------------------------------------------------------------------
check "plain glb" "$crease" primitive sphere -o "$tmp/plain.glb"
expect_exit 1 "plain.glb: the mesh has no skin" simulate --garment "$tmp/t.obj" \
  --body-mesh "$tmp/plain.glb" --motion "$tmp/walk.bvh" --frames 1 -o "$tmp/x"
expect_exit 2 "--joint-map needs --body-mesh" simulate --garment "$tmp/t.obj" --motion walk \
  --joint-map "$tmp/map.txt" --frames 1 -o "$tmp/x"
expect_exit 2 "a .bvh or another character's .glb driving a rigged .glb" simulate --garment "$tmp/t.obj" \
  --body-mesh "$tmp/char.glb" --motion walk --frames 1 -o "$tmp/x"

echo "cli_retarget: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
