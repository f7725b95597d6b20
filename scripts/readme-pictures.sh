#!/usr/bin/env bash
# The README's pictures made again from what the product makes today: the demo's session
# (config/sim.toml on the simulated rig, the default model) relit as scripts/demo.sh relights
# it, and rig evaluate's two charts. Writes docs/images/{relit,two-lamps,exposure-0.02s,
# sweep-first,sweep-last,evaluation-error-vs-time,evaluation-error-vs-storage}.png.
# Usage: scripts/readme-pictures.sh [BUILD_DIR]   (about 2 minutes on 2 cores once built)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
rig="${1:-$here/build}/rig/rig"
images="$here/docs/images"
[ -x "$rig" ] || { echo "readme-pictures: no rig at $rig (scripts/build.sh rig)" >&2; exit 1; }
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
session="$tmp/session"
echo "== the demo's session (dry run) -> $session"
"$rig" capture --config "$here/config/sim.toml" --out "$session" --dry-run > "$tmp/capture.log"
grep -m1 "^model:" "$tmp/capture.log" || true
mkdir -p "$tmp/render"
echo "== relit as scripts/demo.sh relights it"
"$rig" render "$session" --light 45,20 --tonemap ward --out "$tmp/render/relit.png"
"$rig" render "$session" --light 20,10,1,0.35,0.2 --light 75,25,0.25,0.45,1 --tonemap ward \
  --out "$tmp/render/two-lamps.png"
"$rig" render "$session" --light 45,20 --exposure 0.02 --out "$tmp/render/exposure-0.02s.png"
"$rig" render "$session" --sweep 0,15:90,15 --frames 24 --tonemap ward --out "$tmp/render/sweep.avi"
echo "== rig evaluate --dry-run (the charts)"
"$rig" evaluate --dry-run --out "$tmp/evaluation" > "$tmp/evaluate.log"
# Written whole or not at all: each picture copied beside its name, then renamed over it.
put() {
  cp "$1" "$images/.$2.tmp" && mv -f "$images/.$2.tmp" "$images/$2"
  echo "wrote $images/$2"
}
put "$tmp/render/relit.png" relit.png
put "$tmp/render/two-lamps.png" two-lamps.png
put "$tmp/render/exposure-0.02s.png" exposure-0.02s.png
put "$tmp/render/sweep/frame_0000.png" sweep-first.png
put "$tmp/render/sweep/frame_0023.png" sweep-last.png
put "$tmp/evaluation/error_vs_time.png" evaluation-error-vs-time.png
put "$tmp/evaluation/error_vs_storage.png" evaluation-error-vs-storage.png
