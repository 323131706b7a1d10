#!/usr/bin/env bash
# The core's layers (docs/architecture.md): each folder of src/flatland includes only its own
# headers and those of the folders below it. Prints every include that runs up a layer and fails
# if there is one. Usage: tests/layers_check.sh SOURCE_DIR
set -euo pipefail
root=${1:?usage: layers_check.sh SOURCE_DIR}
layers=(base geometry scene storage transport results reference studies)
status=0
for ((i = 0; i < ${#layers[@]}; i++)); do
  layer=${layers[$i]}
  allowed=" ${layers[*]:0:$((i + 1))} "
  [[ -d "$root/src/flatland/$layer" ]] || { echo "layers check: no folder src/flatland/$layer" >&2; exit 2; }
  while IFS= read -r line; do
    file=${line%%:*}
    included=$(sed -E 's/.*#include "flatland\/([a-z_]+)\/.*/\1/' <<<"$line")
    if [[ "$allowed" != *" $included "* ]]; then
      echo "${file#"$root"/}: includes flatland/$included/ from $layer/ (a layer above it)"
      status=1
    fi
  done < <(grep -H '#include "flatland/[a-z_]*/' "$root/src/flatland/$layer"/*.[ch]pp || true)
done
# Every folder of the core is in the list above.
for dir in "$root"/src/flatland/*/; do
  name=$(basename "$dir")
  [[ " ${layers[*]} " == *" $name "* ]] || { echo "src/flatland/$name: not a known layer; add it to tests/layers_check.sh and docs/architecture.md"; status=1; }
done
if ((status != 0)); then
  echo "layers check: the includes above run up a layer (order: ${layers[*]})"
else
  echo "layers check: every include in src/flatland runs down or within its layer"
fi
exit "$status"
