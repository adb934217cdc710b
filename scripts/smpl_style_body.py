#!/usr/bin/python3
"""smpl_style_body.py SRC.glb DST.npz: an SMPL-family model file (the keys SMPL's .npz
release has: v_template, shapedirs, J_regressor, weights, kintree_table, f) made from a
skinned body glb as `crease body -o SRC.glb` writes it, for trying crease's SMPL path
without SMPL's licence. v_template is the glb's rest mesh; one shape direction moves every
vertex away from the vertical axis by 10 % per unit of beta (so FILE.npz:1 is 10 % wider);
J_regressor puts each joint at its rest position by weights over the 48 vertices nearest it
(SMPL's are such sparse averages; the mean of the nearest alone sits on the skin's near side,
and a garment's neckline, sized by the neck joint's distance to the skin, then closes over the
head); weights are the glb's (up to 4 per vertex); SMPL's two hand joints
hang off the wrists, unweighted. Needs numpy (Debian's python3-numpy)."""
import json
import struct
import sys

import numpy as np

SMPL22 = ["pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
          "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
          "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
          "left_wrist", "right_wrist"]
COMPONENTS = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}
DTYPES = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}


def read_glb(path):
    b = open(path, "rb").read()
    if b[:4] != b"glTF":
        sys.exit(f"{path}: not a glb file")
    jlen = struct.unpack_from("<I", b, 12)[0]
    doc = json.loads(b[20:20 + jlen])
    binary = b[20 + jlen + 8:]

    def accessor(i):
        a = doc["accessors"][i]
        v = doc["bufferViews"][a["bufferView"]]
        n = COMPONENTS[a["type"]]
        start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
        return np.frombuffer(binary, DTYPES[a["componentType"]], a["count"] * n,
                             start).reshape(a["count"], n)
    return doc, accessor


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    src, dst = sys.argv[1:3]
    doc, accessor = read_glb(src)
    skins = doc.get("skins", [])
    if not skins:
        sys.exit(f"{src}: no skin (write it with `crease body -o FILE.glb`)")
    prim = doc["meshes"][0]["primitives"][0]
    attr = prim["attributes"]
    pos = accessor(attr["POSITION"]).astype(np.float64)
    joints4 = accessor(attr["JOINTS_0"]).astype(np.int64)
    weights4 = accessor(attr["WEIGHTS_0"]).astype(np.float64)
    faces = accessor(prim["indices"]).reshape(-1, 3).astype(np.int64)
    names = [doc["nodes"][j].get("name") for j in skins[0]["joints"]]
    missing = [n for n in SMPL22 if n not in names]
    if missing:
        sys.exit(f"{src}: the skin lacks SMPL's joint '{missing[0]}'")
    ibm = accessor(skins[0]["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    world = np.linalg.inv(ibm.astype(np.float64))  # each joint's rest frame
    V, J = len(pos), 24
    order = [names.index(n) for n in SMPL22]  # skin joint of SMPL joint j
    rest_joints = np.vstack([world[order, :3, 3], world[order[20], :3, 3],
                             world[order[21], :3, 3]])
    weights = np.zeros((V, J))
    to_smpl = np.array([SMPL22.index(n) if n in SMPL22 else -1 for n in names])
    for k in range(4):
        j = to_smpl[joints4[:, k]]
        ok = (j >= 0) & (weights4[:, k] > 0)
        np.add.at(weights, (np.nonzero(ok)[0], j[ok]), weights4[ok, k])
    weights /= np.maximum(weights.sum(1, keepdims=True), 1e-12)
    reg = np.zeros((J, V))
    K = 48
    for j in range(J):
        # the minimum-norm weights over the K nearest vertices that sum to 1 and average to
        # the joint: w = (1 + (p - m)^T C^-1 (joint - m)) / K, m and C their mean and covariance
        near = np.argsort(((pos - rest_joints[j]) ** 2).sum(1))[:K]
        d = pos[near] - pos[near].mean(0)
        c = d.T @ d / K
        reg[j, near] = (1.0 + d @ np.linalg.solve(c, rest_joints[j] - pos[near].mean(0))) / K
    parent = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
    kintree = np.array([[4294967295 if p < 0 else p for p in parent], list(range(J))],
                       dtype=np.int64)
    shapedirs = np.zeros((V, 3, 1))
    shapedirs[:, 0, 0], shapedirs[:, 2, 0] = 0.1 * pos[:, 0], 0.1 * pos[:, 2]
    with open(dst + ".tmp", "wb") as f:
        np.savez(f, v_template=pos, shapedirs=shapedirs, J_regressor=reg, weights=weights,
                 kintree_table=kintree, f=faces)
    import os
    os.replace(dst + ".tmp", dst)
    print(f"{dst}: {V} vertices, {len(faces)} faces, {J} joints, 1 shape direction")


main()
