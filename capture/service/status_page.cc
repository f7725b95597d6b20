// The status page served at "/": one self-contained HTML file (no network, no external
// script), polling /api/status. The token of a remote daemon comes from the address's
// fragment (#token=...), which browsers never send to the server.
#include "capture/service/http_server.h"

namespace rig {

const char* StatusPageHtml() {
  return R"HTML(<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>rig daemon</title>
<style>
 body{font:14px/1.4 system-ui,sans-serif;margin:0;background:#14171c;color:#dde3ea}
 header{display:flex;gap:1em;align-items:center;padding:.6em 1em;background:#1e232b}
 h1{font-size:1.1em;margin:0} h2{font-size:.95em;margin:.2em 0 .4em;color:#9fb0c3}
 #state{padding:.15em .6em;border-radius:.8em;font-weight:600;background:#3a4250}
 #state.capturing{background:#2f7d4f} #state.processing{background:#2d5f9a}
 #state.stopping{background:#a0772a} #state.fault{background:#a33a3a}
 main{display:grid;grid-template-columns:minmax(280px,1fr) minmax(280px,1fr);gap:1em;padding:1em}
 section{background:#1b1f26;border-radius:6px;padding:.7em 1em}
 .bar{height:14px;background:#2a303a;border-radius:7px;overflow:hidden}
 .bar>div{height:100%;background:#4caf74;width:0}
 dl{display:grid;grid-template-columns:auto 1fr;gap:.15em .8em;margin:.5em 0} dt{color:#9fb0c3}
 dd{margin:0;font-variant-numeric:tabular-nums}
 img{max-width:100%;display:block;background:#000;min-height:60px}
 svg text{fill:#9fb0c3;font-size:10px}
 circle.done{fill:#4caf74} circle.next{fill:#f2c14e;stroke:#fff;stroke-width:2}
 circle.todo{fill:#39414d}
 #faults li{color:#ff9b9b} button{margin-right:.5em}
 .muted{color:#7f8b99}
</style></head><body data-state="loading">
<header><h1>rig daemon</h1><span id="state">loading</span><span id="job" class="muted"></span>
 <span style="flex:1"></span><button id="stop">Stop (park)</button><button id="resume">Resume</button></header>
<main>
<section><h2>Progress</h2>
 <div class="bar"><div id="bar"></div></div>
 <dl><dt>session</dt><dd id="session">-</dd>
  <dt>pose</dt><dd id="pose">-</dd>
  <dt>frames</dt><dd id="frames">-</dd>
  <dt>remaining</dt><dd id="eta">-</dd>
  <dt>model</dt><dd id="model">-</dd>
  <dt>queue</dt><dd id="queue">-</dd></dl>
</section>
<section><h2>Lamp poses</h2><svg id="grid" width="100%" viewBox="0 0 360 170"></svg>
 <div class="muted">horizontal angle across, vertical up; green stored, yellow next</div></section>
<section><h2>Last frame <span id="frame-name" class="muted"></span></h2><img id="frame" alt="no frame yet"></section>
<section><h2>Radiance map (tone-mapped)</h2><img id="radiance" alt="no radiance map yet"></section>
<section style="grid-column:1/-1"><h2>Faults</h2><ul id="faults"><li class="muted" style="color:inherit">none</li></ul></section>
</main>
<script>
"use strict";
const token = (location.hash.match(/token=([^&]+)/) || [])[1];
const headers = token ? {Authorization: "Bearer " + decodeURIComponent(token)} : {};
const $ = id => document.getElementById(id);
let lastFrame = null, lastMaps = -1;
function fmtTime(s) {
  if (s == null) return "-";
  s = Math.round(s); const m = Math.floor(s / 60);
  return m ? m + " min " + (s % 60) + " s" : s + " s";
}
async function image(path, el) {
  try {
    const r = await fetch(path, {headers, cache: "no-store"});
    if (!r.ok) return;
    const url = URL.createObjectURL(await r.blob());
    if (el.dataset.url) URL.revokeObjectURL(el.dataset.url);
    el.dataset.url = url; el.src = url;
  } catch (e) {}
}
function drawGrid(grid) {
  const svg = $("grid"); svg.textContent = "";
  if (!grid.length) return;
  const hs = [...new Set(grid.map(p => p.h_deg))].sort((a, b) => a - b);
  const vs = [...new Set(grid.map(p => p.v_deg))].sort((a, b) => a - b);
  const x = h => 30 + (hs.length > 1 ? (hs.indexOf(h) * 320 / (hs.length - 1)) : 160);
  const y = v => 140 - (vs.length > 1 ? (vs.indexOf(v) * 120 / (vs.length - 1)) : 60);
  const NS = "http://www.w3.org/2000/svg";
  for (const p of grid) {
    const c = document.createElementNS(NS, "circle");
    c.setAttribute("cx", x(p.h_deg)); c.setAttribute("cy", y(p.v_deg));
    c.setAttribute("r", p.state === "next" ? 8 : 6); c.setAttribute("class", p.state);
    c.setAttribute("data-pose", p.name);
    const t = document.createElementNS(NS, "title"); t.textContent = p.name; c.appendChild(t);
    svg.appendChild(c);
  }
  hs.forEach(h => { const t = document.createElementNS(NS, "text"); t.setAttribute("x", x(h) - 6);
    t.setAttribute("y", 162); t.textContent = h + "\u00b0"; svg.appendChild(t); });
  vs.forEach(v => { const t = document.createElementNS(NS, "text"); t.setAttribute("x", 0);
    t.setAttribute("y", y(v) + 3); t.textContent = v + "\u00b0"; svg.appendChild(t); });
}
function render(s) {
  document.body.dataset.state = s.state;
  $("state").textContent = s.state + (s.held ? " (queue held)" : ""); $("state").className = s.state;
  const j = s.job || s.last_job;
  $("job").textContent = j ? "job " + j.id + " " + j.kind + ": " + j.state : "no job yet";
  $("session").textContent = s.session || "-";
  $("pose").textContent = s.pose ? s.pose.name + " (" + s.pose.number + " of " + s.pose.total + ")" :
                          (s.session ? "every pose stored" : "-");
  if (s.frames) {
    $("frames").textContent = s.frames.stored + " of " + s.frames.total +
        " stored (" + s.frames.this_job + " by this job)";
    $("bar").style.width = (100 * s.frames.stored / Math.max(1, s.frames.total)) + "%";
  }
  $("eta").textContent = fmtTime(s.eta_s);
  if (s.model) $("model").textContent = s.model.radiance_maps + " of " + s.model.poses +
      " radiance maps; " + s.model.phase + (s.model.fitting_s != null ? " " + fmtTime(s.model.fitting_s) : "");
  $("queue").textContent = s.queue.length ? s.queue.map(q => q.id + " " + q.kind).join(", ") : "empty";
  drawGrid(s.grid || []);
  const faults = [];
  if (s.last_fault) faults.push("job " + s.last_fault.job + ": " + s.last_fault.error);
  if (s.journal_fault && (!s.last_fault || s.last_fault.error.indexOf(s.journal_fault.error) < 0))
    faults.push("journal: " + s.journal_fault.error);
  if (j && j.state === "failed") faults.push("job " + j.id + " failed: " + j.error);
  $("faults").innerHTML = "";
  for (const f of faults) { const li = document.createElement("li"); li.textContent = f; $("faults").appendChild(li); }
  if (!faults.length) $("faults").innerHTML = '<li class="muted" style="color:inherit">none</li>';
  const lf = s.last_frame ? s.last_frame.file : null;
  if (lf && lf !== lastFrame) { lastFrame = lf; $("frame-name").textContent = lf; image("api/preview/frame.jpg", $("frame")); }
  if (s.model && s.model.radiance_maps !== lastMaps && s.model.radiance_maps > 0) {
    lastMaps = s.model.radiance_maps; image("api/preview/radiance.jpg", $("radiance"));
  }
}
async function poll() {
  try {
    const r = await fetch("api/status", {headers, cache: "no-store"});
    if (r.ok) render(await r.json());
    else { $("state").textContent = "HTTP " + r.status; document.body.dataset.state = "error"; }
  } catch (e) { $("state").textContent = "daemon unreachable"; document.body.dataset.state = "unreachable"; }
  setTimeout(poll, 1000);
}
$("stop").onclick = () => fetch("api/stop", {method: "POST", headers});
$("resume").onclick = () => fetch("api/resume", {method: "POST", headers});
poll();
</script></body></html>
)HTML";
}

}  // namespace rig
