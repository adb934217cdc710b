#!/usr/bin/env python3
"""Edge strain of a simulated cloth: |l / l0 - 1| over the mesh's edges.

    edge_strain.py REST.obj RESULT.obj|RESULT.pc2 [--rest-length L] [--every-frame]

RESULT is a mesh with REST's vertices in the same order (OBJ), or a PC2
point cache of them (its last sample; --every-frame: the largest p99 over
all samples as well). --rest-length L takes every rest edge as L metres
instead of REST's lengths (Blender's grid, whose rest is not written).
Prints one JSON line: mean, p99 and max of the strain, and the edge count.
bench_peers.sh puts it beside the speed so that a fast result that is
stretched or crumpled cannot pass for a good one. No numpy: plain Python
(Debian's python3 alone).
"""
import argparse
import json
import math
import struct
import sys


def fail(msg):
    sys.stderr.write("edge_strain.py: %s\n" % msg)
    sys.exit(2)


def read_obj(path):
    verts, faces = [], []
    try:
        with open(path) as f:
            for n, line in enumerate(f, 1):
                t = line.split()
                if not t:
                    continue
                try:
                    if t[0] == "v":
                        verts.append(tuple(float(x) for x in t[1:4]))
                    elif t[0] == "f":
                        faces.append([int(x.split("/")[0]) - 1 for x in t[1:]])
                except ValueError:
                    fail("%s:%d: malformed %r line" % (path, n, t[0]))
    except OSError as e:
        fail("%s: %s" % (path, e.strerror))
    for f in faces:
        if len(f) < 3 or min(f) < 0 or max(f) >= len(verts):
            fail("%s: a face refers to a vertex that is not there" % path)
    return verts, faces


def read_pc2(path, nv, every):
    try:
        with open(path, "rb") as f:
            head = f.read(32)
            if len(head) < 32 or head[:11] != b"POINTCACHE2":
                fail("%s: not a PC2 file" % path)
            n, = struct.unpack("<i", head[16:20])
            samples, = struct.unpack("<i", head[28:32])
            if n != nv:
                fail("%s: %d points, the rest mesh has %d vertices" % (path, n, nv))
            if samples < 1:
                fail("%s: no samples" % path)
            first = 0 if every else samples - 1
            f.seek(32 + 12 * n * first)
            data = f.read(12 * n * (samples - first))
            if len(data) != 12 * n * (samples - first):
                fail("%s: truncated (%d samples in the header)" % (path, samples))
    except OSError as e:
        fail("%s: %s" % (path, e.strerror))
    a = struct.unpack("<%df" % (3 * n * (samples - first)), data)
    return [[tuple(a[3 * (s * n + i):3 * (s * n + i) + 3]) for i in range(n)]
            for s in range(samples - first)]


def strains(edges, rest, x):
    return sorted(abs(math.dist(x[a], x[b]) / l0 - 1.0) for (a, b), l0 in zip(edges, rest))


def main(argv):
    ap = argparse.ArgumentParser(prog="edge_strain.py", description="Edge strain of a cloth.")
    ap.add_argument("rest", help="rest mesh (OBJ)")
    ap.add_argument("result", help="the result: OBJ, or PC2 (its last sample)")
    ap.add_argument("--rest-length", type=float, help="every rest edge this long, m")
    ap.add_argument("--every-frame", action="store_true",
                    help="also the largest p99 over all of a PC2's samples")
    args = ap.parse_args(argv)
    rest_length = args.rest_length
    if rest_length is not None and not rest_length > 0.0:
        fail("--rest-length must be > 0")
    every = args.every_frame
    verts, faces = read_obj(args.rest)
    edges = sorted({(min(f[i], f[(i + 1) % len(f)]), max(f[i], f[(i + 1) % len(f)]))
                    for f in faces for i in range(len(f))})
    if not edges:
        fail("%s: no faces" % args.rest)
    rest = [rest_length or math.dist(verts[a], verts[b]) for a, b in edges]
    if min(rest) <= 0.0:
        fail("%s: an edge of zero length" % args.rest)
    if args.result.endswith(".pc2"):
        frames = read_pc2(args.result, len(verts), every)
    else:
        x, _ = read_obj(args.result)
        if len(x) != len(verts):
            fail("%s: %d vertices, the rest mesh has %d" % (args.result, len(x), len(verts)))
        frames = [x]
    p99 = lambda s: s[min(len(s) - 1, int(0.99 * len(s)))]
    s = strains(edges, rest, frames[-1])
    out = {"edges": len(edges), "mean": sum(s) / len(s), "p99": p99(s), "max": s[-1]}
    if every:
        out["largest_p99"] = max(p99(strains(edges, rest, x)) for x in frames)
    print(json.dumps(out, separators=(",", ":")))


if __name__ == "__main__":
    main(sys.argv[1:])
