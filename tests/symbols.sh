#!/usr/bin/env bash
# symbols.sh: the static library exports only cr_-prefixed names, so none can
# clash with a user's own functions. Lists the global defined symbols of every
# object in the archive with nm and fails on any other name, printing each with
# its object file.
#
# Compilers add two kinds of names no C code can spell (they hold a dot):
# `.gomp_critical_user_*`, the lock clang's OpenMP emits for an unnamed
# `#pragma omp critical` (one for the whole program, as OpenMP specifies),
# and AddressSanitizer's ODR indicator of each global variable NAME
# (`__odr_asan.NAME` from gcc, `__odr_asan_gen_NAME` from clang), where NAME
# must itself start with cr_.
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
bad=$(awk 'NF >= 2 && $NF !~ /^(__odr_asan(\.|_gen_))?cr_/ && $NF !~ /^\.gomp_critical_user_/ {
             n = split($1, f, ":"); print "  " f[n - 1] ": " $(NF - 1) " " $NF }' <<<"$listing")
if [[ -n $bad ]]; then
  echo "symbols: $lib exports $(wc -l <<<"$bad") global names without the cr_ prefix" \
    "(make them static, or name them cr_<module>_<verb>):" >&2
  echo "$bad" >&2
  exit 1
fi
echo "symbols: all $total global symbols of $lib are cr_-prefixed (compiler-made names aside)"
