# gdsr_diag_seams.py (docs/gdsr.md, Strain) RUN_DIR NPZ: mean (|w_u|-1)^2, (|w_v|-1)^2, (w_u.w_v)^2 over frames 2.. of the high
# triangles whose corners lie in one low face vs those straddling two or more (seams of the
# per-low-triangle residual), for upsampled.pc2, gdsr_raw.pc2, gdsr.pc2, reference.pc2.
import sys, struct, zipfile, io, math, array, ast
run, npz = sys.argv[1], sys.argv[2]
V, F = [], []
for l in open(run + "/high.obj"):
    t = l.split()
    if not t: continue
    if t[0] == "v": V.append(tuple(map(float, t[1:4])))
    elif t[0] == "f": F.append(tuple(int(p.split("/")[0]) - 1 for p in t[1:4]))
def npy(b):
    hl = struct.unpack("<H", b[8:10])[0]; h = ast.literal_eval(b[10:10 + hl].decode())
    a = array.array({"<i4": "i", "<f4": "f", "<i8": "q", "<f8": "d"}[h["descr"]]); a.frombytes(b[10 + hl:]); return a
z = zipfile.ZipFile(npz)
names = z.namelist()
face = None
for n in names:
    a = npy(z.read(n))
    if len(a) == len(V) and a.typecode in "iq": face = a
assert face is not None, names
def pc2(p):
    b = open(p, "rb").read(); _, _, n, _, _, T = struct.unpack("<12siiffi", b[:32])
    a = array.array("f"); a.frombytes(b[32:]); return a, n, T
# rest Dm^-1, u along the first edge
D = []
for (i, j, k) in F:
    a, b, c = V[i], V[j], V[k]
    u = [b[d] - a[d] for d in range(3)]; v = [c[d] - a[d] for d in range(3)]
    lu = math.sqrt(sum(x * x for x in u)); pr = sum(u[d] * v[d] for d in range(3)) / lu
    pe = math.sqrt(max(sum(x * x for x in v) - pr * pr, 0))
    det = lu * pe; D.append((pe / det, -pr / det, 0.0, lu / det))
seam = [not (face[i] == face[j] == face[k]) for (i, j, k) in F]
print("triangles", len(F), "seam", sum(seam))
for name in ("upsampled", "gdsr_raw", "gdsr", "reference"):
    x, n, T = pc2(f"{run}/{name}.pc2")
    s = {True: [0, 0, 0, 0], False: [0, 0, 0, 0]}
    for t in range(2, T):
        o = t * n * 3
        for f, (i, j, k) in enumerate(F):
            d = D[f]; p0 = x[o + 3 * i:o + 3 * i + 3]; p1 = x[o + 3 * j:o + 3 * j + 3]; p2 = x[o + 3 * k:o + 3 * k + 3]
            e1 = [p1[q] - p0[q] for q in range(3)]; e2 = [p2[q] - p0[q] for q in range(3)]
            wu = [e1[q] * d[0] + e2[q] * d[2] for q in range(3)]; wv = [e1[q] * d[1] + e2[q] * d[3] for q in range(3)]
            lu = math.sqrt(sum(q * q for q in wu)); lv = math.sqrt(sum(q * q for q in wv))
            a = s[seam[f]]; a[0] += (lu - 1) ** 2; a[1] += (lv - 1) ** 2; a[2] += sum(wu[q] * wv[q] for q in range(3)) ** 2; a[3] += 1
    print(name, " ".join("%s e_u %.3g e_v %.3g e_uv %.3g" % ("seam" if k else "inner", v[0] / v[3], v[1] / v[3], v[2] / v[3]) for k, v in s.items()))
