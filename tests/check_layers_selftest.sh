#!/usr/bin/env bash
# check_layers_selftest.sh REPO: scripts/check_layers.sh passes on a copy of the tree and
# fails, naming the file and the include, on copies with a planted fault each.
set -u
repo=${1:-$(cd "$(dirname "$0")/.." && pwd)}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
passed=0
failed=0
copy() { # copy DIR: a fresh copy of what the check reads
  rm -rf "$1" && mkdir -p "$1/docs" "$1/scripts"
  cp -r "$repo/src" "$repo/include" "$1/"
  cp "$repo/docs/ARCHITECTURE.md" "$1/docs/"
  cp "$repo/scripts/check_layers.sh" "$1/scripts/"
}
expect() { # expect CODE PATTERN DIR: the check on DIR exits CODE, stderr matching PATTERN
  local code=$1 pattern=$2 dir=$3
  bash "$dir/scripts/check_layers.sh" "$dir" >"$tmp/out" 2>"$tmp/err"
  local got=$?
  if [[ $got -eq $code ]] && grep -Eq -- "$pattern" "$tmp/err" "$tmp/out"; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: want exit $code and /$pattern/, got $got: $(head -c 400 "$tmp/err")" >&2
  fi
}

copy "$tmp/ok"
expect 0 "includes agree" "$tmp/ok"

copy "$tmp/up"
printf '#include "crease/scene.h"\n' >>"$tmp/up/src/body/skeleton.c"
expect 1 "src/body/skeleton.c:[0-9]+: body/ includes \"crease/scene.h\" of the higher layer scene/" "$tmp/up"

copy "$tmp/hdr"
printf '#include "crease/nn.h"\n' >>"$tmp/hdr/include/crease/mesh.h"
expect 1 "include/crease/mesh.h:[0-9]+: geom/ includes \"crease/nn.h\" of the higher layer nn/" "$tmp/hdr"

copy "$tmp/priv"
printf '#include "phys/sim_internal.h"\n' >>"$tmp/priv/src/geom/mesh.c"
expect 1 "src/geom/mesh.c:[0-9]+: geom/ includes \"phys/sim_internal.h\"" "$tmp/priv"

copy "$tmp/missing"
printf '#ifndef X\n#define X\n#endif\n' >"$tmp/missing/include/crease/zzz_new.h"
expect 1 "include/crease/zzz_new.h is missing from .*module table" "$tmp/missing"

copy "$tmp/layer"
mkdir -p "$tmp/layer/src/render2" && printf 'int cr_x;\n' >"$tmp/layer/src/render2/x.c"
expect 1 "src/render2/ is not a layer" "$tmp/layer"

echo "check_layers_selftest: $passed passed, $failed failed"
((failed == 0))
