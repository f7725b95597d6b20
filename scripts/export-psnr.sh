#!/usr/bin/env bash
# What each export format loses on the real icon ($ICON: the NeuralRTI
# example capture, docs/data.md):
# fits PTM and HSH (order 2, sRGB space, least squares, downsampled 2x), exports each to the
# web format at several JPEG qualities (YCbCr as relight writes, and RGB-space planes), .ptm
# and .rti, and prints rig export's "as written, read back" PSNR over the 72 capture lights.
# Usage: scripts/export-psnr.sh [BUILD_DIR]   (default build/)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
rig="${1:-$here/build}/rig/rig"
lp="${ICON:?set ICON to the NeuralRTI example capture folder (docs/data.md)}/dirs.lp"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
for basis in ptm hsh; do
  "$rig" fit --lp "$lp" --basis "$basis" --order 2 --space srgb --method ls --downsample 2 \
    --out "$out/$basis.exr" > /dev/null
  legacy=$([ "$basis" = ptm ] && echo ptm || echo rti)
  n=0
  for args in "--format relight --jpeg-quality 95" "--format relight --jpeg-quality 98" \
              "--format relight --jpeg-quality 100" "--format relight --jpeg-quality 95 --jpeg-rgb" \
              "--format relight --jpeg-quality 100 --jpeg-rgb" "--format $legacy"; do
    n=$((n + 1))
    ext=""; [ "$args" = "--format $legacy" ] && ext=".$legacy"
    db=$("$rig" export "$out/$basis.exr" $args --out "$out/$basis-$n$ext" | sed -n 's/.*as written, read back: \([^ ]*\).*/\1/p')
    bytes=$(du -sb "$out/$basis-$n$ext" | cut -f1)
    printf '%-4s %-48s %8s dB  %9s bytes\n' "$basis" "$args" "$db" "$bytes"
  done
done
