# gdsr_diag_curvature.py (docs/gdsr.md, High band) RUN_DIR: the RMS mean curvature (cotangent
# Laplacian, A_i a third of the one-ring's area) of upsampled, gdsr_raw, gdsr, reference at the
# last frame, and RUN_DIR/NAME_smoothK.pc2 for NAME in upsampled, gdsr, reference, K = 1, 3:
# after K uniform Laplacian half steps, for crease eval's spectrum.
import sys, struct, math, array
run = sys.argv[1]
V, F = [], []
for l in open(run + "/high.obj"):
    t = l.split()
    if not t: continue
    if t[0] == "v": V.append(tuple(map(float, t[1:4])))
    elif t[0] == "f": F.append(tuple(int(p.split("/")[0]) - 1 for p in t[1:4]))
n = len(V)
nb = [set() for _ in range(n)]
for (i, j, k) in F:
    nb[i] |= {j, k}; nb[j] |= {i, k}; nb[k] |= {i, j}
def pc2(p):
    b = open(p, "rb").read(); hdr = b[:32]; _, _, m, _, _, T = struct.unpack("<12siiffi", hdr)
    a = array.array("f"); a.frombytes(b[32:]); return a, m, T, hdr
def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def curv(x, o):
    P = [(x[o + 3 * i], x[o + 3 * i + 1], x[o + 3 * i + 2]) for i in range(n)]
    L = [[0.0, 0.0, 0.0] for _ in range(n)]; A = [0.0] * n
    for (i, j, k) in F:
        for (a, b, c) in ((i, j, k), (j, k, i), (k, i, j)):
            u, v = sub(P[b], P[a]), sub(P[c], P[a])
            cr = math.sqrt(dot(cross(u, v), cross(u, v))) + 1e-20
            w = 0.5 * dot(u, v) / cr  # cot at a, weights edge b-c
            for q in range(3):
                L[b][q] += w * (P[c][q] - P[b][q]); L[c][q] += w * (P[b][q] - P[c][q])
        ar = 0.5 * math.sqrt(dot(cross(sub(P[j], P[i]), sub(P[k], P[i])), cross(sub(P[j], P[i]), sub(P[k], P[i]))))
        for q in (i, j, k): A[q] += ar / 3
    return [(dot(L[i], L[i]) / (4 * A[i] * A[i]) if A[i] > 0 else 0.0, A[i]) for i in range(n)]
for name in ("upsampled", "gdsr_raw", "gdsr", "reference"):
    x, m, T, hdr = pc2(f"{run}/{name}.pc2")
    h = curv(x, (T - 1) * n * 3)
    print("%-10s frame %d: H_rms %.3g 1/m" % (name, T - 1, math.sqrt(sum(a * hh for hh, a in h) / sum(a for _, a in h))))
for name, steps in ((a, b) for a in ("upsampled", "gdsr", "reference") for b in (1, 3)):
    x, m, T, hdr = pc2(f"{run}/{name}.pc2")
    y = array.array("f", x)
    for t in range(T):
        o = t * n * 3
        for _ in range(steps):
            P = y[o:o + 3 * n]
            for i in range(n):
                s = [0.0, 0.0, 0.0]
                for j in nb[i]:
                    for q in range(3): s[q] += P[3 * j + q]
                for q in range(3): y[o + 3 * i + q] = 0.5 * P[3 * i + q] + 0.5 * s[q] / len(nb[i])
    with open(f"{run}/{name}_smooth{steps}.pc2", "wb") as f: f.write(hdr); f.write(y.tobytes())
