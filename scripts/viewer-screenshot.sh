#!/usr/bin/env bash
# docs/images/viewer.png: the relighting page of the real icon ($ICON: the NeuralRTI
# example capture, docs/data.md; fitted with rig fit's default PCA model), two lamps, as headless
# Chromium (SwiftShader) draws it from file://.
# Usage: scripts/viewer-screenshot.sh [BUILD_DIR] [OUT.png]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
rig="${1:-$here/build}/rig/rig"
png="${2:-$here/docs/images/viewer.png}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"$rig" fit --lp "${ICON:?set ICON to the NeuralRTI example capture folder (docs/data.md)}/dirs.lp" --out "$tmp/icon" > /dev/null
"$rig" view "$tmp/icon" --out "$tmp/view"
url="file://$tmp/view/index.html?light=-0.5,0.45,0.74,1,0.85,0.7,1;0.6,-0.2,0.77,0.45,0.6,1,0.8"
chromium --headless=new --no-sandbox --disable-gpu --use-angle=swiftshader --enable-unsafe-swiftshader \
  --user-data-dir="$tmp/profile" --window-size=1000,640 --virtual-time-budget=15000 \
  --host-resolver-rules="MAP * ~NOTFOUND" --screenshot="$png" "$url" 2> /dev/null
echo "wrote $png"
