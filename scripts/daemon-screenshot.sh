#!/usr/bin/env bash
# The status page's screenshot in docs/images/daemon-status.png: a simulated session run by
# `rig daemon` at a fifth of real device latencies, photographed by headless Chromium while
# it captures, then SIGTERM (the rig parks; the session is left resumable in the temp folder).
# Usage: scripts/daemon-screenshot.sh [BUILD_DIR] [OUT.png]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
out=${2:-$root/docs/images/daemon-status.png}
tmp=$(mktemp -d)
cp "$root/config/sim.toml" "$tmp/sim.toml"
sed -i 's/^latency_scale = 0.0.*/latency_scale = 0.2/' "$tmp/sim.toml"
"$build/rig/rig" daemon --listen 127.0.0.1:0 --sessions-root "$tmp" > "$tmp/daemon.log" 2>&1 &
pid=$!
trap 'kill -TERM $pid 2>/dev/null || true; wait $pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  port=$(grep -o 'listening on http://127.0.0.1:[0-9]*' "$tmp/daemon.log" | grep -o '[0-9]*$' || true)
  [ -n "$port" ] && break
  sleep 0.1
done
"$build/rig/rig" capture --config "$tmp/sim.toml" --out "$tmp/session" --daemon "http://127.0.0.1:$port"
# Until a dozen poses are stored and a radiance map exists.
for _ in $(seq 600); do
  "$build/rig/rig" status --daemon "127.0.0.1:$port" --json > "$tmp/status.json"
  python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); sys.exit(0 if s["poses_done"]>=12 and s["model"]["radiance_maps"]>=1 else 1)' "$tmp/status.json" 2>/dev/null && break
  sleep 0.2
done
chromium --headless=new --no-sandbox --disable-gpu --hide-scrollbars --window-size=960,820 \
  --virtual-time-budget=3000 --screenshot="$out" "http://127.0.0.1:$port/" 2>/dev/null
"$build/rig/rig" status --daemon "127.0.0.1:$port"
echo "screenshot: $out (session $tmp/session)"
