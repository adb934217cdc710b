# gdsr_diag_cstar.py (docs/gdsr.md, Strain) DATA MOTION: E_u, E_v, E_uv (crease eval's, mean over high triangles, frames 2..) of
# S[C*], the barycentric upsampling of the coarse target C* (the high simulation at the high
# vertex nearest each low vertex at rest: the operator gdsr used before), of S[C*] with C* at
# each low vertex's closest point on the high rest mesh (a 3-D stand-in for the UV operator
# gdsr uses now), and of S[C].
import sys, struct, zipfile, math, array, ast
data, motion = sys.argv[1], sys.argv[2]
def obj(p):
    V, F = [], []
    for l in open(p):
        t = l.split()
        if not t: continue
        if t[0] == "v": V.append(tuple(map(float, t[1:4])))
        elif t[0] == "f": F.append(tuple(int(q.split("/")[0]) - 1 for q in t[1:4]))
    return V, F
g = data + "/garments/normal/"
VL, FL = obj(g + "tshirt_low.obj"); VH, FH = obj(g + "tshirt_high.obj")
def npy(b):
    hl = struct.unpack("<H", b[8:10])[0]; h = ast.literal_eval(b[10:10 + hl].decode())
    a = array.array({"<i4": "i", "<f4": "f", "<i8": "q", "<f8": "d"}[h["descr"]]); a.frombytes(b[10 + hl:]); return a, h
z = zipfile.ZipFile(g + "tshirt_high_from_low.npz"); arrs = {n: npy(z.read(n)) for n in z.namelist()}
face = [a for a, h in arrs.values() if a.typecode in "iq" and len(a) == len(VH)][0]
bary = [a for a, h in arrs.values() if a.typecode in "fd" and len(a) == 3 * len(VH)][0]
near = []
for p in VL:
    near.append(min(range(len(VH)), key=lambda i: sum((VH[i][d] - p[d]) ** 2 for d in range(3))))
# closest point of each low vertex on the high triangles around its nearest high vertex
inc = [[] for _ in VH]
for f, t in enumerate(FH):
    for q in t: inc[q].append(f)
def closest(p, f):
    """(squared distance, barycentrics) of p's clamped projection onto high triangle f"""
    a, b, c = (VH[q] for q in FH[f])
    e0 = [b[d] - a[d] for d in range(3)]; e1 = [c[d] - a[d] for d in range(3)]; w = [p[d] - a[d] for d in range(3)]
    d00 = sum(x * x for x in e0); d01 = sum(e0[d] * e1[d] for d in range(3)); d11 = sum(x * x for x in e1)
    d20 = sum(w[d] * e0[d] for d in range(3)); d21 = sum(w[d] * e1[d] for d in range(3)); den = d00 * d11 - d01 * d01
    v = max((d11 * d20 - d01 * d21) / den, 0); u = max((d00 * d21 - d01 * d20) / den, 0)
    if v + u > 1: v, u = v / (v + u), u / (v + u)
    q = [a[d] + v * e0[d] + u * e1[d] for d in range(3)]
    return sum((q[d] - p[d]) ** 2 for d in range(3)), (1 - v - u, v, u)
proj = []
for i, p in enumerate(VL):
    cands = [(closest(p, f), f) for f in inc[near[i]]]
    (dist, b), f = min(cands)
    proj.append((f, b))
def pc2(p):
    b = open(p, "rb").read(); _, _, n, _, _, T = struct.unpack("<12siiffi", b[:32])
    a = array.array("f"); a.frombytes(b[32:]); return a, n, T
D = []
for (i, j, k) in FH:
    a, b, c = VH[i], VH[j], VH[k]
    u = [b[d] - a[d] for d in range(3)]; v = [c[d] - a[d] for d in range(3)]
    lu = math.sqrt(sum(x * x for x in u)); pr = sum(u[d] * v[d] for d in range(3)) / lu
    pe = math.sqrt(max(sum(x * x for x in v) - pr * pr, 0)); det = lu * pe
    D.append((pe / det, -pr / det, 0.0, lu / det))
def strain(X):
    s = [0, 0, 0]
    for f, (i, j, k) in enumerate(FH):
        d = D[f]; e1 = [X[j][q] - X[i][q] for q in range(3)]; e2 = [X[k][q] - X[i][q] for q in range(3)]
        wu = [e1[q] * d[0] + e2[q] * d[2] for q in range(3)]; wv = [e1[q] * d[1] + e2[q] * d[3] for q in range(3)]
        s[0] += (math.sqrt(sum(q * q for q in wu)) - 1) ** 2; s[1] += (math.sqrt(sum(q * q for q in wv)) - 1) ** 2
        s[2] += sum(wu[q] * wv[q] for q in range(3)) ** 2
    return [x / len(FH) for x in s]
def up(L):
    out = []
    for i in range(len(VH)):
        t = FL[face[i]]; b = bary[3 * i:3 * i + 3]
        out.append([sum(b[q] * L[t[q]][d] for q in range(3)) for d in range(3)])
    return out
hi, nh, T = pc2(f"{data}/sequences/tshirt_high_normal_{motion}/garment.pc2")
lo, nl, _ = pc2(f"{data}/sequences/tshirt_low_normal_{motion}/garment.pc2")
acc = {"S[C*] nearest vertex": [0, 0, 0], "S[C*] closest point": [0, 0, 0], "S[C]": [0, 0, 0]}
frames = range(2, T, 4)
for t in frames:
    H = [hi[(t * nh + i) * 3:(t * nh + i) * 3 + 3] for i in range(nh)]
    C = [lo[(t * nl + i) * 3:(t * nl + i) * 3 + 3] for i in range(nl)]
    P = [[sum(b[q] * H[FH[f][q]][d] for q in range(3)) for d in range(3)] for f, b in proj]
    for name, L in (("S[C*] nearest vertex", [H[near[i]] for i in range(nl)]),
                    ("S[C*] closest point", P), ("S[C]", C)):
        s = strain(up(L)); acc[name] = [acc[name][q] + s[q] for q in range(3)]
for k, v in acc.items():
    print(k, "e_u %.4g e_v %.4g e_uv %.4g" % tuple(x / len(frames) for x in v), "over frames 2..%d step 4" % (T - 1))
