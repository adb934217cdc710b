#!/usr/bin/env python3
"""make_character.py SRC.glb DST.glb STYLE [proportions] [tpose]: a rigged character made
from crease's skinned mannequin (`crease pose-body -o SRC.glb`) the way another tool's
would differ: the skin's joints renamed from SMPL's names to Mixamo's ("mixamo") or to
meaningless boneNN ("bones"); with "proportions", longer legs (x1.12) and spine (x1.15)
and shorter arms (x0.9), by the joints' rest offsets; with "tpose", the arms raised 40
degrees into a T-pose, by the shoulders' rest rotations (the mesh follows both through
its inverse bind matrices, as a reader poses it by the nodes' rest); either drops the
file's own animation. Standard library only."""
import json
import math
import struct
import sys

SMPL = ["pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
        "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
        "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
        "left_wrist", "right_wrist"]
MIXAMO = ["Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1",
          "LeftFoot", "RightFoot", "Spine2", "LeftToeBase", "RightToeBase", "Neck",
          "LeftShoulder", "RightShoulder", "Head", "LeftArm", "RightArm", "LeftForeArm",
          "RightForeArm", "LeftHand", "RightHand"]
# a bone's length factor, by the joint it ends at
SCALE = {"left_knee": 1.12, "right_knee": 1.12, "left_ankle": 1.12, "right_ankle": 1.12,
         "left_elbow": 0.9, "right_elbow": 0.9, "left_wrist": 0.9, "right_wrist": 0.9,
         "spine2": 1.15, "spine3": 1.15}


def main():
    src, dst, style = sys.argv[1:4]
    proportions = "proportions" in sys.argv[4:]
    tpose = "tpose" in sys.argv[4:]
    half = math.radians(40) / 2  # the shoulders' turn about +Z, left up, right up
    b = open(src, "rb").read()
    jlen = struct.unpack_from("<I", b, 12)[0]
    doc = json.loads(b[20:20 + jlen])
    rest = b[20 + jlen:]
    for n in doc["nodes"]:
        name = n.get("name")
        if name not in SMPL:
            continue
        i = SMPL.index(name)
        if proportions and name in SCALE and "translation" in n:
            n["translation"] = [SCALE[name] * t for t in n["translation"]]
        if tpose and name in ("left_shoulder", "right_shoulder"):
            s = math.sin(half) * (1 if name == "left_shoulder" else -1)
            n["rotation"] = [0.0, 0.0, s, math.cos(half)]
        n["name"] = "mixamorig:" + MIXAMO[i] if style == "mixamo" else "bone%02d" % i
    if proportions or tpose:
        doc.pop("animations", None)
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    out = b[:12] + struct.pack("<I", len(j)) + b[16:20] + j + rest
    out = out[:8] + struct.pack("<I", len(out)) + out[12:]
    open(dst, "wb").write(out)


main()
