#!/usr/bin/env bash
# The wall time of a collection through Snakemake on two cores (-j2) against the same rig
# commands run one after another in a plain shell loop, and Snakemake with one job at a time
# (-j1: the workflow's own overhead). Each variant starts from the same freshly captured
# simulated sessions (frames only) and the shared .lp capture; capturing is not timed.
#   bench/collection_bench.sh [BUILD_DIR] [SESSIONS] [WIDTH] [HEIGHT]
# defaults: build 4 160 120. Prints one line per variant and the ratios.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-$here/build}" && pwd)
n=${2:-4}
width=${3:-160}
height=${4:-120}
rig="$build/rig/rig"
lp_src="${ICON:?set ICON to the NeuralRTI example capture folder (docs/data.md)}"
work=$(mktemp -d /tmp/rig-collection-bench.XXXXXX)
trap 'rm -rf "$work"' EXIT
command -v snakemake > /dev/null || { echo "collection_bench: snakemake is not installed" >&2; exit 2; }

sed -e "s/^width = 320/width = $width/" -e "s/^height = 240/height = $height/" \
  "$here/config/sim.toml" > "$work/sim.toml"
"$rig" capture --config "$work/sim.toml" --out "$work/S" --dry-run --no-progress --no-process > /dev/null
rm -f "$work/S/.lock"

make_root() {  # make_root DIR: n copies of the session and a link to the .lp capture
  mkdir -p "$1"
  for i in $(seq 1 "$n"); do cp -r "$work/S" "$1/S$i"; done
  ln -s "$lp_src" "$1/icon"
}
init() {  # init COLLECTION ROOT
  "$rig" collection init "$1" --root "$2" --formats relight,ptm --lp-fit-arg=--downsample \
    --lp-fit-arg=2 --session-evaluate-arg=--quick --no-evaluate-lp > /dev/null
}

# 1. Snakemake, two jobs at once.
make_root "$work/r2"; init "$work/c2" "$work/r2"
(cd "$work/c2" && /usr/bin/time -f "%e %U %S" -o "$work/t_j2" snakemake -j2 --quiet > "$work/j2.log" 2>&1)

# 2. Snakemake, one job at a time.
make_root "$work/r1"; init "$work/c1" "$work/r1"
(cd "$work/c1" && /usr/bin/time -f "%e %U %S" -o "$work/t_j1" snakemake -j1 --quiet > "$work/j1.log" 2>&1)

# 3. The same rig commands, one after another, into the same layout (rules in share/rig/Snakefile).
make_root "$work/r0"; init "$work/c0" "$work/r0"
cat > "$work/loop.sh" <<EOF_LOOP
set -euo pipefail
rig="$rig"; work="$work"; n=$n; lp_src="$lp_src"
EOF_LOOP
cat >> "$work/loop.sh" <<'EOF_LOOP'
  cd "$work/c0"
  for i in $(seq 1 "$n"); do
    s="$work/r0/S$i"; r="results/S$i"; mkdir -p "$r/export" logs
    "$rig" process "$s" --hdr-only > /dev/null
    ls "$s/hdr" > "$r/hdr.txt"
    "$rig" process "$s" > /dev/null
    for f in relight ptm; do
      out="$r/export/$f"; [ $f = ptm ] && { mkdir -p "$out"; out="$out/model.ptm"; }
      "$rig" export "$s" --format $f --out "$out" > /dev/null
    done
    "$rig" evaluate "$s" --out "$r/evaluate" --quick > /dev/null
    "$rig" render "$s" --light 45,20 --out "$r/render.png" > /dev/null
    ln -sfn "$s" "$r/source"
  done
  r=results/icon__dirs; mkdir -p "$r/export/ptm" logs/fit
  "$rig" fit --lp "$lp_src/dirs.lp" --out "$r/model" --report "$r/fit.md" --downsample 2 > logs/fit/icon__dirs.log
  "$rig" export "$r/model" --format relight --out "$r/export/relight" > /dev/null
  "$rig" export "$r/model" --format ptm --out "$r/export/ptm/model.ptm" > /dev/null
  "$rig" render "$r/model" --light 45,20 --out "$r/render.png" > /dev/null
  ln -sfn "$lp_src/dirs.lp" "$r/source"
  "$rig" collection report . > /dev/null
EOF_LOOP
/usr/bin/time -f "%e %U %S" -o "$work/t_seq" bash "$work/loop.sh" > "$work/seq.log" 2>&1
read -r t_seq u_seq s_seq < "$work/t_seq"
read -r t_j1 u_j1 s_j1 < "$work/t_j1"
read -r t_j2 u_j2 s_j2 < "$work/t_j2"
cpu() { echo "$1 + $2" | bc; }

printf "collection of %d sessions (%dx%d, 40 poses) + the icon (.lp, --downsample 2); %d cores, load %s\n" \
  "$n" "$width" "$height" "$(nproc)" "$(cut -d' ' -f1-3 /proc/loadavg)"
printf "  rig commands one after another (shell loop): wall %7.2f s, CPU %7.2f s\n" "$t_seq" "$(cpu $u_seq $s_seq)"
printf "  snakemake -j1 (the same commands as jobs):   wall %7.2f s, CPU %7.2f s (wall %+.2f s against the loop)\n" \
  "$t_j1" "$(cpu $u_j1 $s_j1)" "$(echo "$t_j1 - $t_seq" | bc)"
printf "  snakemake -j2:                               wall %7.2f s, CPU %7.2f s (%.2fx the loop's speed)\n" \
  "$t_j2" "$(cpu $u_j2 $s_j2)" "$(echo "$t_seq / $t_j2" | bc -l)"
