#!/usr/bin/env bash
# symbols.sh: the static library exports only cr_-prefixed names, so none can
# clash with a user's own functions. Lists the global defined symbols of every
# object in the archive with nm and fails on any other name, printing each with
# its object file.
#
# One exception: `.gomp_critical_user_*`, the lock clang's OpenMP emits for an
# unnamed `#pragma omp critical`. The OpenMP specification makes that lock one
# for the whole program, and no C code can spell a name with a dot.
#
# Usage: symbols.sh LIBCREASE.a [NM]
set -euo pipefail
lib=${1:?usage: symbols.sh LIBCREASE.a [NM]}
nm=${2:-nm}
[[ -f $lib ]] || { echo "symbols: $lib: no such file" >&2; exit 1; }

# -A: "archive:object.o:address type name" (address absent for some types)
listing=$("$nm" -A -g --defined-only "$lib")
total=$(awk 'NF >= 2' <<<"$listing" | wc -l)
if [[ $total -lt 100 ]]; then
  echo "symbols: $nm found only $total global symbols in $lib (expected hundreds)" >&2
  exit 1
fi
bad=$(awk 'NF >= 2 && $NF !~ /^cr_/ && $NF !~ /^\.gomp_critical_user_/ {
             n = split($1, f, ":"); print "  " f[n - 1] ": " $(NF - 1) " " $NF }' <<<"$listing")
if [[ -n $bad ]]; then
  echo "symbols: $lib exports $(wc -l <<<"$bad") global names without the cr_ prefix" \
    "(make them static, or name them cr_<module>_<verb>):" >&2
  echo "$bad" >&2
  exit 1
fi
omp=$(awk 'NF >= 2 && $NF ~ /^\.gomp_critical_user_/' <<<"$listing" | wc -l)
echo "symbols: $((total - omp)) global symbols of $lib, all cr_-prefixed (and $omp OpenMP locks)"
