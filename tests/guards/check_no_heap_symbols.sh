#!/usr/bin/env bash
# usage: check_no_heap_symbols.sh NM LIBRARY
# Fails (exit 1) when LIBRARY references any heap allocation, exception allocation or thread-safe
# static guard symbol, printing each offending symbol with the object file that wants it.
set -euo pipefail
nm_tool=$1
library=$2
[ -f "$library" ] || { echo "check_no_heap_symbols: no library at $library" >&2; exit 2; }
forbidden='^(malloc|calloc|realloc|free|aligned_alloc|posix_memalign|memalign|valloc|pvalloc|strdup|strndup)$|^operator new|^operator delete|^__cxa_allocate_exception$|^__cxa_throw$|^__cxa_guard_'
# nm -A -u lines read "archive:object: U symbol"; symbols may contain spaces once demangled.
offenders=$("$nm_tool" -C -u -A "$library" |
  awk -v re="$forbidden" '$2 == "U" { obj = $1; sym = $0; sub(/^[^ ]+ +U +/, "", sym); if (sym ~ re) print obj " " sym }')
if [ -n "$offenders" ]; then
  echo "heap guard: $(basename "$library") references forbidden symbols:"
  printf '%s\n' "$offenders" | sed 's/^/  /'
  exit 1
fi
count=$("$nm_tool" -C -u "$library" | grep -c ' U ' || true)
echo "heap guard: $(basename "$library") clean ($count undefined symbols checked)"
