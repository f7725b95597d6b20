#!/usr/bin/env bash
# The layer check holds for the tree, and it fails, naming file and line, on a tree with one
# include that runs upwards (process/ including capture/, sim/ including rig/), a model family
# that includes another family, or one that names a header outside every layer.
set -uo pipefail
src=$1
check="$src/scripts/check-layers.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0
expect() {  # name, wanted exit status, wanted text, tree
  local name=$1 want=$2 text=$3 tree=$4 out rc
  out=$("$check" "$tree" 2>&1); rc=$?
  if [ "$rc" -eq "$want" ] && grep -qF -- "$text" <<<"$out"; then
    pass=$((pass + 1)); echo "ok   $name"
  else
    fail=$((fail + 1)); echo "FAIL $name (exit $rc, wanted $want with '$text'):"; echo "$out"
  fi
}
expect "the source tree" 0 "every include points down the layers" "$src"

mk() { mkdir -p "$tmp/$1/$(dirname "$2")"; printf '%s\n' "${@:3}" > "$tmp/$1/$2"; }
mk up1 process/model/fit.cc '// fit' '#include "process/io/exr_io.h"' '#include "capture/devices/camera.h"'
expect "process including capture" 1 'process/model/fit.cc:3: process/model includes "capture/devices/camera.h"' "$tmp/up1"
mk up2 sim/sim_lamp.h '#include "rig/backends.h"'
expect "sim including rig" 1 'sim/sim_lamp.h:1: sim includes "rig/backends.h"' "$tmp/up2"
mk up3 capture/plan/pose.h '#include "capture/session/session_store.h"'
expect "plan including session" 1 'capture/plan/pose.h:1:' "$tmp/up3"
mk up4 process/io/exr_io.cc '#include "process/model/harmonic/model.h"'
expect "io including model" 1 'process/io/exr_io.cc:1:' "$tmp/up4"
mk up5 capture/daemon/daemon.cc '#include "process/hdr.h"'
expect "a header outside every layer" 1 'belongs to no layer' "$tmp/up5"
mk peer process/model/pca/pca.cc '#include "process/model/light_samples.h"' '#include "process/model/harmonic/basis.h"'
expect "a family including another family" 1 'process/model/pca/pca.cc:2: process/model/pca includes "process/model/harmonic/basis.h" from process/model/harmonic, a peer' "$tmp/peer"
mk shared process/model/light_samples.cc '#include "process/model/neural/neural.h"'
expect "what the families share including a family" 1 'process/model/light_samples.cc:1: process/model includes' "$tmp/shared"
mk across process/model/any/load_model.cc '#include "process/model/pca/pca.h"' '#include "process/model/harmonic/model.h"' '#include "process/model/samples.h"'
expect "across families including families" 0 "every include points down" "$tmp/across"
mk writer process/render/picture.cc '// a picture' '  cv::imwrite(path, img);'
expect "a write around the one writer" 1 'process/render/picture.cc:2: writes a file around the one writer' "$tmp/writer"
mk stream rig/commands/report.cc '  std::ofstream f(a.report);'
expect "an ofstream to an output" 1 'rig/commands/report.cc:1: writes a file around' "$tmp/stream"
mk down rig/main.cc '#include "sim/world.h"' '#include "capture/daemon/daemon.h"' '#include "config/log.h"'
expect "downward includes" 0 "every include points down" "$tmp/down"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
