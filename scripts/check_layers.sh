#!/usr/bin/env bash
# check_layers.sh [REPO]: docs/ARCHITECTURE.md's layers and module table match the includes.
#
# The layer order is read from the code block under "## Layers" (one `name/` a line, the
# highest first), the module table from the rows under "## Modules and their headers":
# each header in the first column belongs to the layer of the src/<layer>/ paths in the
# second. Then it fails, naming the file and the line, when
#   - a file under src/ (or a public header in include/crease/) includes a crease/*.h
#     header of a higher layer than its own (a src file's layer is its first folder under
#     src/; a public header's is its table row's);
#   - a file under src/ includes a private header of a higher layer ("nn/tape.h": the
#     first folder names the layer);
#   - a header in include/crease/ is missing from the table, or a row names no src/ path
#     or paths in two layers;
#   - a src/ folder is not a layer in the list.
# A table row for a header that does not exist (yet) is reported, not failed. Run by
# ctest as `check_layers` (CMakeLists.txt). Exit 0 when all is well, 1 otherwise.
set -u
repo=${1:-$(cd "$(dirname "$0")/.." && pwd)}
doc=$repo/docs/ARCHITECTURE.md
fail=0
problem() {
  echo "check_layers: $*" >&2
  fail=1
}
[[ -f $doc ]] || { echo "check_layers: $doc: missing" >&2; exit 1; }

# ---- the layer order: rank 0 is the lowest -------------------------------------------
mapfile -t layers_top_down < <(awk '
  /^## Layers/ { in_section = 1; next }
  /^## / { in_section = 0 }
  in_section && /^```/ { in_block = !in_block; next }
  in_section && in_block && match($0, /^[a-z_]+\//) { print substr($0, 1, RLENGTH - 1) }
' "$doc")
((${#layers_top_down[@]} > 0)) || { echo "check_layers: $doc: no layer list under ## Layers" >&2; exit 1; }
declare -A rank
n=${#layers_top_down[@]}
for ((i = 0; i < n; i++)); do rank[${layers_top_down[i]}]=$((n - 1 - i)); done

for d in "$repo"/src/*/; do
  d=$(basename "$d")
  [[ -n ${rank[$d]+x} ]] || problem "src/$d/ is not a layer in $doc's ## Layers list"
done

# ---- the module table: header -> layer -------------------------------------------------
declare -A header_layer
# awk gives each row as: line number, its headers, its distinct src/ layers (spaces between)
while IFS=$'\t' read -r line headers dirs; do
  read -r -a dirs <<<"$dirs"
  if ((${#dirs[@]} == 0)); then
    problem "$doc:$line: row for $headers names no src/ path"
    continue
  fi
  if ((${#dirs[@]} > 1)); then
    problem "$doc:$line: row for $headers has files in several layers: ${dirs[*]}"
    continue
  fi
  for h in $headers; do
    header_layer[$h]=${dirs[0]}
    [[ -f $repo/include/crease/$h ]] || echo "check_layers: note: $doc:$line lists $h, which include/crease/ does not have (yet)" >&2
  done
done < <(awk -F'|' '
  /^## Modules and their headers/ { in_section = 1; next }
  /^## / { in_section = 0 }
  in_section && /^\| `/ {
    h = ""; rest = $2
    while (match(rest, /`[a-z0-9_]*\.h`/)) {
      h = h (h == "" ? "" : " ") substr(rest, RSTART + 1, RLENGTH - 2)
      rest = substr(rest, RSTART + RLENGTH)
    }
    d = ""; delete seen; rest = $3
    while (match(rest, /src\/[a-z_]*\//)) {
      x = substr(rest, RSTART + 4, RLENGTH - 5)
      if (!(x in seen)) { seen[x] = 1; d = d (d == "" ? "" : " ") x }
      rest = substr(rest, RSTART + RLENGTH)
    }
    print NR "\t" h "\t" d
  }
' "$doc")

for f in "$repo"/include/crease/*.h; do
  h=$(basename "$f")
  [[ -n ${header_layer[$h]+x} ]] || problem "include/crease/$h is missing from $doc's module table"
done

# ---- the includes ----------------------------------------------------------------------
# Every #include "crease/X.h" and "dir/X.h" of a file is at its layer or below. One grep
# over the whole tree (a process per file made this check take seconds).
while IFS=: read -r file lineno inc; do
  rel=${file#"$repo"/}
  if [[ $rel == src/* ]]; then
    layer=${rel#src/}
    layer=${layer%%/*}
  else
    layer=${header_layer[${rel##*/}]:-} # a public header: its table row's layer
  fi
  own=${rank[$layer]:-}
  [[ -n $own ]] || continue
  inc=${inc#*\"}
  inc=${inc%%\"*}
  if [[ $inc == crease/* ]]; then
    target=${header_layer[${inc#crease/}]:-}
    [[ -n $target ]] || continue # reported above, or not a public header
  elif [[ $inc == */* ]]; then
    target=${inc%%/*}
    [[ -n ${rank[$target]+x} ]] || continue
  else
    continue # same folder
  fi
  if ((rank[$target] > own)); then
    problem "$rel:$lineno: $layer/ includes \"$inc\" of the higher layer $target/"
  fi
done < <(grep -rn --include='*.[ch]' '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' \
  "$repo/src" "$repo/include/crease" | sort -t: -k1,1 -k2,2n)

if ((fail)); then
  echo "check_layers: FAILED (docs/ARCHITECTURE.md: ## Layers and ## Modules and their headers)" >&2
  exit 1
fi
echo "check_layers: ${#header_layer[@]} headers in ${n} layers, includes agree"
