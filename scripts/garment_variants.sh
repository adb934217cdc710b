#!/usr/bin/env bash
# garment_variants.sh: the picture grid of random garment variants in docs/garments.md:
# `crease garment --random` for a few types and seeds (4000 vertices, default mannequin),
# the garments and copies of the body set side by side (4 columns, 1.35 m apart) in two
# merged OBJ files, one `crease render` of both (garments blue, bodies grey).
# Usage: garment_variants.sh PATH_TO_CREASE OUT.png [TYPE:SEED ...]
set -euo pipefail
crease=$1 out=$2
shift 2
list=("$@")
[[ ${#list[@]} -gt 0 ]] || list=(tshirt:1 tshirt:2 longsleeve:1 longsleeve:2 vest:1 trousers:1
  skirt:1 skirt:2 dress:1 dress:2 jumpsuit:1 jumpsuit:2)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$crease" body -o "$tmp/body.obj" 2>/dev/null
names=()
for ts in "${list[@]}"; do
  t=${ts%:*} s=${ts#*:}
  "$crease" garment --type "$t" --random --seed "$s" --res 4000 -o "$tmp/${t}_$s.obj" --json |
    tail -n 1
  names+=("${t}_$s")
done
# Offset each copy and renumber the faces' v/vt/vn indices.
python3 - "$tmp" "${names[@]}" <<'PY'
import sys
tmp, names, cols = sys.argv[1], sys.argv[2:], 4
def merge(src_of, out):
    lines, base = [], [0, 0, 0]
    for i, n in enumerate(names):
        dx, dy, count = (i % cols) * 1.35, -(i // cols) * 2.0, [0, 0, 0]
        for l in open(src_of(n)).read().splitlines():
            t = l.split()
            if not t:
                continue
            if t[0] == 'v':
                lines.append("v %.6f %.6f %s" % (float(t[1]) + dx, float(t[2]) + dy, t[3]))
                count[0] += 1
            elif t[0] in ('vt', 'vn'):
                lines.append(l)
                count[1 if t[0] == 'vt' else 2] += 1
            elif t[0] == 'f':
                corners = []
                for c in t[1:]:
                    p = c.split('/')
                    corners.append('/'.join(str(int(x) + base[k]) if x else ''
                                            for k, x in enumerate(p)))
                lines.append("f " + " ".join(corners))
        base = [b + c for b, c in zip(base, count)]
    open(out, 'w').write("\n".join(lines) + "\n")
merge(lambda n: "%s/%s.obj" % (tmp, n), tmp + "/garments.obj")
merge(lambda n: tmp + "/body.obj", tmp + "/bodies.obj")
PY
"$crease" render "$tmp/garments.obj" "$tmp/bodies.obj" --size 1000 --yaw 12 --pitch 5 -o "$out"
