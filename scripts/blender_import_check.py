"""blender_import_check.py: Blender imports a skinned, animated crease glb as engines do (issue
52), checked by its own evaluation, not by crease's reader.

    blender -b --python-exit-code 1 -P scripts/blender_import_check.py -- \
        BODY.glb BODY.pc2 FRAME FRAME ...

BODY.glb is `crease pose-body ... -o BODY.glb` (or `crease body -o`), BODY.pc2 the same motion
written by `crease pose-body ... -o BODY.pc2`. Blender's glTF importer builds an armature, the
skinned mesh with an Armature modifier and the animation as an action; at each FRAME the
evaluated mesh (the armature posed by the action, the mesh deformed by Blender's own
skinning) is compared with crease's posed vertices of that frame: the largest distance from
a Blender vertex to the nearest crease vertex (the importer splits vertices at UV seams, so
vertices are matched by position), beside how far the mesh moved from the first FRAME.
Also prints the armature's bones and the action's keyed range. Exits 1 when any frame is
more than 1 mm off. The scene's rate is set to the file's (30 fps) before importing, so glTF
time t is Blender frame 30 t.

Debian's Blender 3.4 importer calls numpy.bool, which numpy 1.24 removed: it is given back as
the builtin bool, which is what it aliased.
"""
import struct
import sys

import bpy
import mathutils
import numpy

if not hasattr(numpy, "bool"):
    numpy.bool = bool


def read_pc2(path):
    raw = open(path, "rb").read()
    nv, = struct.unpack_from("<i", raw, 16)
    nf, = struct.unpack_from("<i", raw, 28)
    data = struct.unpack_from("<%df" % (nf * nv * 3), raw, 32)
    return nf, nv, data


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    glb, pc2, frames = argv[0], argv[1], [int(f) for f in argv[2:]]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.render.fps = 30
    bpy.ops.import_scene.gltf(filepath=glb)
    arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
    body = next(o for o in bpy.data.objects if o.type == "MESH" and
                any(m.type == "ARMATURE" for m in o.modifiers))
    action = arm.animation_data.action if arm.animation_data else None
    print("armature %s: %d bones; mesh %s: %d vertices; action %s, frames %s" %
          (arm.name, len(arm.data.bones), body.name, len(body.data.vertices),
           action.name if action else None, tuple(action.frame_range) if action else None))
    nf, nv, data = read_pc2(pc2)
    worst_all, first = 0.0, None
    for f in frames:
        if f >= nf:
            sys.exit("frame %d: the point cache has %d" % (f, nf))
        bpy.context.scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        ev = body.evaluated_get(dg)
        mesh = ev.to_mesh()
        # Blender is Z-up: its (x, y, z) is glTF's (x, -z, y)
        pts = []
        for v in mesh.vertices:
            w = ev.matrix_world @ v.co
            pts.append((w.x, w.z, -w.y))
        ev.to_mesh_clear()
        tree = mathutils.kdtree.KDTree(nv)
        for i in range(nv):
            o = 3 * (f * nv + i)
            tree.insert(data[o:o + 3], i)
        tree.balance()
        worst = max(tree.find(p)[2] for p in pts)
        if first is None:
            first, moved = pts, 0.0
        else:
            moved = max((mathutils.Vector(a) - mathutils.Vector(b)).length
                        for a, b in zip(first, pts))
        head = arm.matrix_world @ arm.pose.bones[0].head
        print("frame %d: Blender's skinned mesh %.2e m from crease's at most (%d vertices; moved "
              "up to %.3f m from frame %d); root bone head at (%.3f, %.3f, %.3f)" %
              (f, worst, len(pts), moved, frames[0], head.x, head.z, -head.y))
        worst_all = max(worst_all, worst)
    sys.exit(0 if worst_all < 1e-3 else 1)


main()
