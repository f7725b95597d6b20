// The status page's script (capture/service/page/): polls api/status, shows it, and sends the
// stop and resume actions. The token of a remote daemon comes from the address's fragment
// (#token=...), which browsers never send to the server; the page token (given in the page's
// meta tag as it is served) proves an action comes from this page, not another site's.
"use strict";
const token = (location.hash.match(/token=([^&]+)/) || [])[1];
const headers = token ? {Authorization: "Bearer " + decodeURIComponent(token)} : {};
const pageToken = document.querySelector('meta[name="rig-page-token"]').content;
const actionHeaders = Object.assign({"Content-Type": "application/json", "X-Rig-Page-Token": pageToken}, headers);
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
    const t = document.createElementNS(NS, "title");
    t.textContent = p.name + (p.choice ? " (chosen " + p.choice + ")" : p.state === "allowed" ? " (allowed, not chosen)" : "");
    c.appendChild(t);
    svg.appendChild(c);
    if (p.choice) {  // an adaptive grid: the order the poses were chosen in
      const n = document.createElementNS(NS, "text"); n.setAttribute("class", "choice");
      n.setAttribute("x", x(p.h_deg)); n.setAttribute("y", y(p.v_deg) + 2.5); n.textContent = p.choice;
      svg.appendChild(n);
    }
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
  const ch = s.choice;
  $("choice-row").hidden = $("choice").hidden = !ch;
  $("grid-legend").textContent = ch ? "horizontal angle across, vertical up; numbered in the order chosen, green stored, " +
      "yellow next, dashed allowed" : "horizontal angle across, vertical up; green stored, yellow next";
  if (ch) $("choice").textContent = ch.chosen + " of at most " + ch.max_poses + " poses chosen (" + ch.allowed +
      " allowed); predicted error " + (ch.predicted_rms != null ? ch.predicted_rms.toFixed(2) + " codes (" +
      ch.floor_rms.toFixed(2) + " with every pose)" : "- (the seed)") + (ch.stopped ? "; stopped: " + ch.stopped : "");
  $("queue").textContent = s.queue.length ? s.queue.map(q => q.id + " " + q.kind).join(", ") : "empty";
  drawGrid(s.grid || []);
  const faults = [];
  if (s.last_fault) faults.push("job " + s.last_fault.job + ": " + s.last_fault.error);
  if (s.journal_fault && (!s.last_fault || s.last_fault.error.indexOf(s.journal_fault.error) < 0))
    faults.push("journal: " + s.journal_fault.error);
  if (j && j.state === "failed") faults.push("job " + j.id + " failed: " + j.error);
  $("faults").textContent = "";
  for (const f of faults) { const li = document.createElement("li"); li.textContent = f; $("faults").appendChild(li); }
  if (!faults.length) { const li = document.createElement("li"); li.className = "none"; li.textContent = "none"; $("faults").appendChild(li); }
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
function action(path) {
  return fetch(path, {method: "POST", headers: actionHeaders, body: "{}", cache: "no-store"})
      .then(r => r.json().then(j => { if (!r.ok) $("state").textContent = "HTTP " + r.status + ": " + j.error; }))
      .catch(e => { $("state").textContent = String(e); });
}
$("stop").onclick = () => action("api/stop");
$("resume").onclick = () => action("api/resume");
poll();
