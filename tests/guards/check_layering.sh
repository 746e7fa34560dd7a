#!/usr/bin/env bash
# usage: check_layering.sh ROOT
# core/ includes only core/, Eigen and the standard library; hal/ never includes sim_hal/; sim_hal/
# includes only hal's capability interfaces (hal/*.hpp at the top of hal/), never a real driver.
set -uo pipefail
root=$1
status=0
report() { echo "layering: $1"; status=1; }

if [ -d "$root/core" ]; then
  while IFS= read -r line; do
    report "core may include only core/, Eigen and the standard library: $line"
  done < <(grep -rnE '^\s*#\s*include\s*[<"]' "$root/core" --include='*.hpp' --include='*.cpp' --include='*.h' |
           grep -vE '#\s*include\s*"core/' | grep -vE '#\s*include\s*<(Eigen/|unsupported/Eigen/)' |
           grep -vE '#\s*include\s*<[a-z_0-9]+(\.h)?>')
fi
if [ -d "$root/hal" ]; then
  while IFS= read -r line; do report "hal must not include sim_hal: $line"; done \
    < <(grep -rnE '#\s*include\s*"sim_hal/' "$root/hal" || true)
fi
if [ -d "$root/sim_hal" ]; then
  while IFS= read -r line; do report "sim_hal may include only hal's interfaces (hal/*.hpp): $line"; done \
    < <(grep -rnE '#\s*include\s*"hal/[^"]*/' "$root/sim_hal" || true)
fi
[ $status -eq 0 ] && echo "layering: clean"
exit $status
