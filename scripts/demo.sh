#!/usr/bin/env bash
# The main job on the embedded default: sets everything up, then runs a whole session on the
# simulated rig (config/sim.toml: 40 lamp poses x 7 exposures), which merges every bracket
# into a radiance map and fits the reflectance model, and relights the result.
# Outputs go to out/demo-<time>/ (a new session each run: nothing is ever overwritten).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
echo "== build: the rig executable only (37 steps; a first build takes about 4 minutes on a quiet"
echo "   2-core machine, seconds after that; scripts/test.sh builds the rest)"
bash scripts/build.sh rig
echo "== built in $(( $(date +%s) - start )) s"
rig=build/rig/rig
session="out/demo-$(date +%Y%m%d-%H%M%S)"
mkdir -p out
echo "== capture (dry run on the simulated rig) -> $session"
$rig capture --config config/sim.toml --out "$session" --dry-run
ln -sfn "$(basename "$session")" out/latest
echo "== relight"
mkdir -p "$session/render"
$rig render "$session" --light 45,20 --tonemap ward --out "$session/render/relit.png"
$rig render "$session" --light 20,10,1,0.35,0.2 --light 75,25,0.25,0.45,1 --tonemap ward \
  --out "$session/render/two-lamps.png"
$rig render "$session" --light 45,20 --exposure 0.02 --out "$session/render/exposure-0.02s.png"
$rig render "$session" --sweep 0,15:90,15 --frames 24 --tonemap ward --out "$session/render/sweep.avi"
echo
echo "session:      $session (journal.jsonl, frames/, hdr/, calib/, model/, truth/)"
echo "relit:        $session/render/relit.png"
echo "two lamps:    $session/render/two-lamps.png"
echo "exposure:     $session/render/exposure-0.02s.png"
echo "sweep:        $session/render/sweep.avi (and its frames in $session/render/sweep/)"
