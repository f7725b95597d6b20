#!/usr/bin/env bash
# Fails when an #include runs against the layers. The units, lowest first; a file may include
# its own unit and any unit below it, never one above:
#   config < process/{io,hdr,model,geometry,render,export,evaluate} < capture/{plan,devices,session,daemon,service}
#   < sim < rig
# (tests/ and bench/ may include anything.) Usage: check-layers.sh [SOURCE_ROOT]
set -euo pipefail
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
units=(config process/io process/hdr process/model process/geometry process/render process/export process/evaluate
       capture/plan capture/devices capture/session capture/daemon capture/service sim rig)

rank_of() {  # the rank of the unit a path (file or include) belongs to, -1 if none
  local p=$1 i
  for i in "${!units[@]}"; do
    case "$p" in "${units[$i]}"/*) echo "$i"; return ;; esac
  done
  echo -1
}

bad=0 files=0
cd "$root"
while IFS= read -r -d '' file; do
  rel=${file#./}
  own=$(rank_of "$rel")
  [ "$own" -ge 0 ] || continue
  files=$((files + 1))
  while IFS=: read -r line inc; do
    r=$(rank_of "$inc")
    # A project folder that is not a unit (process/foo.h at the top of process/) is an error too.
    if [ "$r" -lt 0 ]; then
      case "$inc" in config/*|process/*|capture/*|sim/*|rig/*)
        echo "$rel:$line: includes \"$inc\", which belongs to no layer"; bad=$((bad + 1)) ;;
      esac
      continue
    fi
    if [ "$r" -gt "$own" ]; then
      echo "$rel:$line: ${units[$own]} includes \"$inc\" from ${units[$r]}, a layer above it" \
           "(config < process < capture < sim < rig)"
      bad=$((bad + 1))
    fi
  done < <(grep -n -o -E '^[[:space:]]*#[[:space:]]*include[[:space:]]*"[^"]+"' "$file" |
           sed -E 's/^([0-9]+):.*"([^"]+)"/\1:\2/')
done < <(find . \( -name '*.h' -o -name '*.cc' -o -name '*.cpp' -o -name '*.hpp' \) \
           -not -path './build*' -not -path './.git/*' -print0)

if [ "$bad" -gt 0 ]; then
  echo "check-layers: $bad include(s) against the layers in $files files"
  exit 1
fi
echo "check-layers: $files files, every include points down the layers"
