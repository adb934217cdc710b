#!/usr/bin/env python3
"""make_character.py SRC.glb DST.glb STYLE [proportions] [tpose] [animated] [extra] [armature]:
a rigged character made from crease's skinned mannequin (`crease pose-body -o SRC.glb`) the
way another tool's would differ: the skin's joints renamed from SMPL's names to Mixamo's
("mixamo") or to meaningless boneNN ("bones"); with "proportions", longer legs (x1.12) and
spine (x1.15) and shorter arms (x0.9), by the joints' rest offsets; with "tpose", the arms
raised 40 degrees into a T-pose, by the shoulders' rest rotations (the mesh follows both
through its inverse bind matrices, as a reader poses it by the nodes' rest); either drops
the file's own animation unless "animated" keeps it (its keys then pose the joints as they
posed the mannequin, from the new rest); "extra" adds joints no body has: a "root" joint on
the floor under the hips (its translation taken out of the hips' keys), and end joints
above the head and past the toes, none weighting a vertex; "armature" puts the skeleton
under an "Armature" node turned 90 degrees about X with scale 0.01, as Blender writes a
Mixamo rig (a Z-up armature in centimetres): every joint's rest, keys and inverse bind
matrix re-expressed in it, so the skin is posed exactly as before. Standard library only."""
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
# end joints: (name by style, parent SMPL joint, offset from it, m)
ENDS = [(("HeadTop_End", "bone_top"), "head", (0.0, 0.15, 0.0)),
        (("LeftToe_End", "bone_ltoe"), "left_foot", (0.0, -0.02, 0.06)),
        (("RightToe_End", "bone_rtoe"), "right_foot", (0.0, -0.02, 0.06))]
ARM_TURN = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))  # +90 deg about X, x y z w
ARM_SCALE = 0.01


def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def qconj(q):
    return (-q[0], -q[1], -q[2], q[3])


def qrot(q, v):
    return qmul(qmul(q, (v[0], v[1], v[2], 0.0)), qconj(q))[:3]


def mat_from(q, s):
    """Column-major 4x4 of rotation q (x y z w) times uniform scale s."""
    x, y, z, w = q
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m = [0.0] * 16
    for c in range(3):
        for k in range(3):
            m[4 * c + k] = r[k][c] * s
    m[15] = 1.0
    return m


def mat_mul(a, b):
    return [sum(a[4 * k + r] * b[4 * c + k] for k in range(4)) for c in range(4) for r in range(4)]


def translate(t):
    m = mat_from((0, 0, 0, 1), 1.0)
    m[12:15] = list(t)
    return m


class Bin:
    """The BIN chunk, read and rewritten through accessors (tightly packed floats)."""

    def __init__(self, doc, data):
        self.doc, self.data = doc, bytearray(data)

    def span(self, ai):
        a = self.doc["accessors"][ai]
        v = self.doc["bufferViews"][a["bufferView"]]
        n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a["type"]]
        return v.get("byteOffset", 0) + a.get("byteOffset", 0), a["count"], n

    def read(self, ai):
        off, count, n = self.span(ai)
        return [list(struct.unpack_from("<%df" % n, self.data, off + 4 * n * i))
                for i in range(count)]

    def write(self, ai, rows):
        off, count, n = self.span(ai)
        assert len(rows) == count
        for i, r in enumerate(rows):
            struct.pack_into("<%df" % n, self.data, off + 4 * n * i, *r)

    def append(self, rows, typ):
        """A new float accessor of rows at the end of the chunk; its index."""
        while len(self.data) % 4:
            self.data.append(0)
        off = len(self.data)
        for r in rows:
            self.data += struct.pack("<%df" % len(r), *r)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": off,
                                        "byteLength": len(self.data) - off})
        self.doc["accessors"].append({"bufferView": len(self.doc["bufferViews"]) - 1,
                                      "componentType": 5126, "count": len(rows), "type": typ})
        return len(self.doc["accessors"]) - 1


def channels(doc, node, path):
    for a in doc.get("animations", []):
        for ch in a["channels"]:
            if ch["target"].get("node") == node and ch["target"]["path"] == path:
                yield a["samplers"][ch["sampler"]]["output"]


def main():
    src, dst, style = sys.argv[1:4]
    opts = set(sys.argv[4:])
    proportions, tpose = "proportions" in opts, "tpose" in opts
    half = math.radians(40) / 2  # the shoulders' turn about +Z, left up, right up
    b = open(src, "rb").read()
    jlen = struct.unpack_from("<I", b, 12)[0]
    doc = json.loads(b[20:20 + jlen])
    blen = struct.unpack_from("<I", b, 20 + jlen)[0]
    bin_ = Bin(doc, b[28 + jlen:28 + jlen + blen])
    nodes = doc["nodes"]
    index = {n.get("name"): i for i, n in enumerate(nodes)}
    for n in nodes:
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
    if (proportions or tpose) and "animated" not in opts:
        doc.pop("animations", None)
    skin = doc["skins"][0]
    hips = index["pelvis"]
    if "extra" in opts:
        prefix = "mixamorig:" if style == "mixamo" else ""
        for names, parent, off in ENDS:
            nodes.append({"name": prefix + names[0 if style == "mixamo" else 1],
                          "translation": list(off)})
            nodes[index[parent]].setdefault("children", []).append(len(nodes) - 1)
        ht = nodes[hips]["translation"]
        floor = [ht[0], 0.0, ht[2]]
        nodes.append({"name": "root" if style == "mixamo" else "bone_root",
                      "translation": floor, "children": [hips]})
        root = len(nodes) - 1
        nodes[hips]["translation"] = [ht[0] - floor[0], ht[1], ht[2] - floor[2]]
        for out in channels(doc, hips, "translation"):
            bin_.write(out, [[v[0] - floor[0], v[1], v[2] - floor[2]] for v in bin_.read(out)])
        scene = doc["scenes"][doc.get("scene", 0)]["nodes"]
        scene[scene.index(hips)] = root
        added = list(range(len(nodes) - 1 - len(ENDS), len(nodes)))
        skin["joints"] = skin["joints"] + added  # appended: JOINTS_0 keeps its indices
        skin["skeleton"] = root
        world = {}  # the new joints' rest world positions (their parents turn no offset)

        def position(i):
            if i in world:
                return world[i]
            par = next((k for k, n in enumerate(nodes) if i in n.get("children", [])), None)
            t = nodes[i].get("translation", [0, 0, 0])
            p = t if par is None else [a + c for a, c in zip(position(par), t)]
            world[i] = p
            return p
        ibm = bin_.read(skin["inverseBindMatrices"])
        ibm += [translate([-x for x in position(i)]) for i in added]
        skin["inverseBindMatrices"] = bin_.append(ibm, "MAT4")
    if "armature" in opts:
        top = skin.get("skeleton", hips)
        inv_turn = qconj(ARM_TURN)
        for j in skin["joints"]:  # L' = A^-1 L A: translations and rotations into the armature
            n = nodes[j]
            if "translation" in n:
                n["translation"] = [x / ARM_SCALE for x in qrot(inv_turn, n["translation"])]
            if "rotation" in n:
                n["rotation"] = list(qmul(qmul(inv_turn, n["rotation"]), ARM_TURN))
            for out in channels(doc, j, "translation"):
                bin_.write(out, [[x / ARM_SCALE for x in qrot(inv_turn, v)]
                                 for v in bin_.read(out)])
            for out in channels(doc, j, "rotation"):
                bin_.write(out, [list(qmul(qmul(inv_turn, v), ARM_TURN)) for v in bin_.read(out)])
        nodes.append({"name": "Armature", "rotation": list(ARM_TURN),
                      "scale": [ARM_SCALE] * 3, "children": [top]})
        scene = doc["scenes"][doc.get("scene", 0)]["nodes"]
        scene[scene.index(top)] = len(nodes) - 1
        a_inv = mat_from(inv_turn, 1.0 / ARM_SCALE)  # IBM' = A^-1 IBM
        ibm = [mat_mul(a_inv, m) for m in bin_.read(skin["inverseBindMatrices"])]
        skin["inverseBindMatrices"] = bin_.append(ibm, "MAT4")
    while len(bin_.data) % 4:
        bin_.data.append(0)
    doc["buffers"][0]["byteLength"] = len(bin_.data)
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<I", len(j)) + b"JSON" + j + struct.pack("<I", len(bin_.data)) + \
        b"BIN\0" + bytes(bin_.data)
    open(dst, "wb").write(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)


main()
