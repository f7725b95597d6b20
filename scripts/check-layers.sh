#!/usr/bin/env bash
# Fails when an #include runs against the layers. The units, lowest first; a file may include
# its own unit and any unit of a lower rank, never one above, nor a peer of its own rank:
#   config < process/{io < hdr < model < (model/harmonic | model/pca | model/neural)
#            < (model/session | model/any) < geometry < render < export < evaluate}
#   < capture/{plan < devices < session < daemon < service} < sim < rig
# process/model/ itself holds what every model family shares; each family (harmonic, pca,
# neural) is a peer of the others and includes none of them; the session's streamed fit
# (model/session) and what works across families (model/any: reading any model, the choice
# across families) stand above the families.
# (tests/ and bench/ may include anything.) Usage: check-layers.sh [SOURCE_ROOT]
set -euo pipefail
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
# unit:rank; peers share a rank.
unit_ranks=(config:0 process/io:1 process/hdr:2 process/model:3
            process/model/harmonic:4 process/model/pca:4 process/model/neural:4
            process/model/session:5 process/model/any:5
            process/geometry:6 process/render:7 process/export:8 process/evaluate:9
            capture/plan:10 capture/devices:11 capture/session:12 capture/daemon:13
            capture/service:14 sim:15 rig:16)

unit_of() {  # the unit a path (file or include) belongs to (the longest that matches), "" if none
  local p=$1 e u best=""
  for e in "${unit_ranks[@]}"; do
    u=${e%%:*}
    case "$p" in "$u"/*) [ ${#u} -gt ${#best} ] && best=$u ;; esac
  done
  echo "$best"
}
rank_of_unit() {
  local e
  for e in "${unit_ranks[@]}"; do [ "${e%%:*}" = "$1" ] && { echo "${e##*:}"; return; }; done
  echo -1
}

bad=0 files=0
cd "$root"
while IFS= read -r -d '' file; do
  rel=${file#./}
  own_unit=$(unit_of "$rel")
  [ -n "$own_unit" ] || continue
  own=$(rank_of_unit "$own_unit")
  files=$((files + 1))
  while IFS=: read -r line inc; do
    inc_unit=$(unit_of "$inc")
    # A project folder that is not a unit (process/foo.h at the top of process/) is an error too.
    if [ -z "$inc_unit" ]; then
      case "$inc" in config/*|process/*|capture/*|sim/*|rig/*)
        echo "$rel:$line: includes \"$inc\", which belongs to no layer"; bad=$((bad + 1)) ;;
      esac
      continue
    fi
    r=$(rank_of_unit "$inc_unit")
    if [ "$r" -gt "$own" ]; then
      echo "$rel:$line: $own_unit includes \"$inc\" from $inc_unit, a layer above it" \
           "(config < process < capture < sim < rig)"
      bad=$((bad + 1))
    elif [ "$r" -eq "$own" ] && [ "$inc_unit" != "$own_unit" ]; then
      echo "$rel:$line: $own_unit includes \"$inc\" from $inc_unit, a peer of its own rank" \
           "(a model family includes no other family; what they share lives in process/model/)"
      bad=$((bad + 1))
    fi
  done < <(grep -n -o -E '^[[:space:]]*#[[:space:]]*include[[:space:]]*"[^"]+"' "$file" |
           sed -E 's/^([0-9]+):.*"([^"]+)"/\1:\2/')
done < <(find . \( -name '*.h' -o -name '*.cc' -o -name '*.cpp' -o -name '*.hpp' \) \
           -not -path './build*' -not -path './.git/*' -print0)

# Every file the product creates goes through the one writer (config/atomic_file.h: a fresh
# temporary, O_EXCL|O_NOFOLLOW, renamed over the target): no direct cv::imwrite, std::ofstream,
# fopen for writing, copy_file or VideoWriter to an output outside it. The allowlist: the writer
# itself, and the video writer, which opens its file by name inside StagedFile's private folder.
writers=0
while IFS= read -r hit; do
  case "$hit" in
    ./config/atomic_file.cc:*) continue ;;
    ./process/render/relight.cc:*VideoWriter*) continue ;;
  esac
  hit=${hit#./}; file=${hit%%:*}; rest=${hit#*:}; line=${rest%%:*}; code=${rest#*:}
  echo "$file:$line: writes a file around the one writer (config/atomic_file.h: WriteFileAtomic," \
       "AtomicFile, AtomicFolder, WriteImageFile): ${code#"${code%%[![:space:]]*}"}"
  writers=$((writers + 1))
done < <(find ./config ./process ./capture ./sim ./rig \( -name '*.h' -o -name '*.cc' \) \
           -not -path './build*' 2>/dev/null -print0 |
         xargs -0 -r grep -n -E 'cv::imwrite|std::ofstream|[^a-z_]fopen\([^)]*"[wa]|copy_file\(|cv::VideoWriter' /dev/null |
         grep -v -E ':[0-9]+:[[:space:]]*//')

if [ "$bad" -gt 0 ] || [ "$writers" -gt 0 ]; then
  [ "$bad" -gt 0 ] && echo "check-layers: $bad include(s) against the layers in $files files"
  [ "$writers" -gt 0 ] && echo "check-layers: $writers write(s) around the one writer"
  exit 1
fi
echo "check-layers: $files files, every include points down the layers"
