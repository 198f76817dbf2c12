// The operator's dashboard of downhole's real-time SIL runtime (served by downhole.sil.dashboard).
// Data arrive over the WebSocket /ws in SI; they are shown in the display units the server sends
// (state.units: {quantity: {unit, factor}}). Charts: uPlot, shipped with the package.
// The token (when one is set) travels in the HttpOnly cookie set by GET /?token=...
"use strict";

const UNITS = {bit_axial_velocity: "m/s", bit_angular_velocity: "rad/s", wob: "N", tob: "N m",
  hook_load: "N", surface_torque: "N m", top_drive_angular_velocity: "rad/s",
  top_drive_axial_velocity: "m/s", reference_axial_velocity: "m/s",
  reference_angular_velocity: "rad/s", time: "s"};

// one entry per chart: quantity (display unit), series: [label, trend channel, colour, dashed]
const CHARTS = [
  {id: "rpm", title: "Rotary speed", q: "rotary_speed", series: [
    ["surface", "top_drive_angular_velocity", "#1f77b4", false],
    ["bit", "bit_angular_velocity", "#d62728", false],
    ["bit reference", "reference_angular_velocity", "#2ca02c", true]]},
  {id: "torque", title: "Surface torque", q: "torque", series: [
    ["surface torque", "surface_torque", "#9467bd", false]]},
  {id: "hook", title: "Hook load", q: "force", series: [
    ["hook load", "hook_load", "#8c564b", false]]},
  {id: "wob", title: "Weight on bit", q: "force", series: [
    ["WOB", "wob", "#ff7f0e", false]]},
  {id: "rop", title: "Rate of penetration", q: "rop", series: [
    ["ROP", "bit_axial_velocity", "#17becf", false],
    ["bit reference", "reference_axial_velocity", "#2ca02c", true]]},
  {id: "severity", title: "Stick-slip severity (max - min) / (2 mean) of bit rpm", q: null,
   axis: "severity (-)", series: [["severity", "stick_slip_severity", "#e377c2", false]]},
  {id: "depth", title: "Bit depth (axial position from the start)", q: "depth", series: [
    ["bit depth", "bit_axial_position", "#393b79", false]]},
];
const MAX_POINTS = 20000;

const store = {t: [], cols: {}};
const charts = {};
let units = null, filled = false, dirty = false, ctrlFilled = false;
window.dashboard = {charts, store, CHARTS};

function $(id) { return document.getElementById(id); }

function post(path, body) {
  return fetch(path, {method: "POST", headers: {"Content-Type": "application/json"},
    body: JSON.stringify(body || {})}).then(r => r.ok ? ($("refused").textContent = "", null)
      : r.json().then(j => {
        $("refused").textContent = path + ": " + j.detail;
        shown = {};  // a refused value does not stay in its field: the next update restores it
        if (document.activeElement) document.activeElement.blur();
      }));
}

$("start").onclick = () => post("/api/start");
$("stop").onclick = () => post("/api/stop");
$("ctrl_on").onclick = () => post("/api/controller", {on: true});
$("ctrl_off").onclick = () => post("/api/controller", {on: false});
let ctrlPicked = false;  // the operator's pick is not overwritten by the server's state
$("ctrl_select").onchange = () => { ctrlPicked = true; };
$("ctrl_apply").onclick = () => {
  ctrlPicked = false;
  post("/api/controller/select", {name: $("ctrl_select").value});
};
// the bit reference in display units; the API takes SI
$("apply_ref").onclick = () => post("/api/reference", {
  axial: parseFloat($("ref_axial").value) / factor("rop"),
  angular: parseFloat($("ref_angular").value) / factor("rotary_speed")});
$("apply_sp").onclick = () => {
  const body = {};
  for (const [id, key] of [["sp_rpm", "surface_rpm"], ["sp_wob", "wob"], ["sp_rop", "rop"]]) {
    const el = $(id);
    if (!el.disabled && el.value.trim() !== "") body[key] = Number(el.value);
  }
  post("/api/setpoints", body);
};

function fmt(x) {
  if (x === null || x === undefined) return "-";
  const a = Math.abs(x);
  return (a !== 0 && (a < 1e-3 || a >= 1e5)) ? x.toExponential(4) : x.toFixed(4);
}
function factor(q) { return q && units ? units[q].factor : 1; }
function unitLabel(q) { return q && units ? units[q].unit : "-"; }

function chartWidth() {
  const w = $("charts").clientWidth;
  return Math.max(520, Math.floor(w >= 1160 ? (w - 10) / 2 : w) - 10);
}

function makeCharts() {
  const host = $("charts");
  for (const c of CHARTS) {
    const div = document.createElement("div");
    div.className = "chart"; div.id = "chart_" + c.id; host.appendChild(div);
    const u = unitLabel(c.q);
    const opts = {
      title: c.title + (c.q ? " (" + u + ")" : ""), width: chartWidth(), height: 210,
      scales: {x: {time: false}, y: c.id === "severity" ? {range: (self, lo, hi) =>
        [0, Math.max(1, (hi || 0) * 1.1)]} : {}},
      axes: [{label: "time (s)", stroke: "#333", grid: {stroke: "#eee"}, ticks: {stroke: "#ccc"}},
             {label: c.q ? u : c.axis, stroke: "#333", size: 64, grid: {stroke: "#eee"},
              ticks: {stroke: "#ccc"}}],
      series: [{label: "time (s)"}].concat(c.series.map(([label, , color, dashed]) => ({
        label: label + (c.q ? " (" + u + ")" : ""), stroke: color, width: 2,
        dash: dashed ? [8, 5] : undefined, spanGaps: false}))),
      legend: {show: true},
    };
    charts[c.id] = new uPlot(opts, [[]].concat(c.series.map(() => [])), div);
  }
  window.addEventListener("resize", () => {
    for (const id in charts) charts[id].setSize({width: chartWidth(), height: 210});
  });
}

function ingest(trend, reset) {
  if (reset) { store.t = []; store.cols = {}; }
  if (!trend || !trend.time || trend.time.length === 0) return;
  const n = trend.time.length;
  if (store.t.length && trend.time[0] < store.t[store.t.length - 1]) {
    store.t = []; store.cols = {};
  }
  for (const c of CHARTS) for (const [, key] of c.series) {
    const col = store.cols[key] || (store.cols[key] = new Array(store.t.length).fill(null));
    const src = trend[key];
    for (let i = 0; i < n; i++) col.push(src ? src[i] : null);
  }
  for (let i = 0; i < n; i++) store.t.push(trend.time[i]);
  if (store.t.length > MAX_POINTS) {  // thin the older half
    const half = Math.floor(store.t.length / 2);
    const thin = a => a.filter((_, i) => i >= half || i % 2 === 0);
    store.t = thin(store.t);
    for (const k in store.cols) store.cols[k] = thin(store.cols[k]);
  }
  dirty = true;
}

function redraw() {
  if (!dirty || !units) return;
  dirty = false;
  for (const c of CHARTS) {
    const f = factor(c.q);
    const ys = c.series.map(([, key]) => {
      const col = store.cols[key] || [];
      // the depth is the advance from the first recorded row (a steady start is not at 0)
      const first = c.id === "depth" ? (col.find(v => v !== null) ?? 0) : 0;
      return col.map(v => v === null ? null : (v - first) * f);
    });
    charts[c.id].setData([store.t.slice()].concat(ys));
  }
}
setInterval(redraw, 200);

function fillControls(s) {
  if (!filled && units) {
    const sp = s.setpoints;
    const put = (id, v, q) => {
      const el = $(id);
      if (v === null || v === undefined) {
        el.disabled = true; el.value = ""; el.placeholder = "n/a";
        el.title = "WOB follows from the feed on a velocity-driven top (set ROP)";
      } else el.value = +(v * factor(q)).toPrecision(5);
    };
    put("sp_rpm", sp.surface_speed, "rotary_speed");
    put("sp_wob", sp.wob, "force");
    put("sp_rop", sp.rop, "rop");
    for (const el of document.querySelectorAll(".u")) el.textContent = unitLabel(el.dataset.q);
    filled = true;
  }
  if (!ctrlFilled) {
    const sel = $("ctrl_select");
    for (const c of s.controllers) {
      const o = document.createElement("option"); o.value = c.name; o.textContent = c.label;
      sel.appendChild(o);
    }
    ctrlFilled = true;
  }
  if (!ctrlPicked) $("ctrl_select").value = s.controller || "off";
}

// The fields follow the server's set-points and reference whenever they change (a set-point
// moves the reference too), except the one the operator is typing in.
let shown = {};
function follow(s) {
  if (!units) return;
  for (const [id, v, q] of [["sp_rpm", s.setpoints.surface_speed, "rotary_speed"],
                            ["sp_wob", s.setpoints.wob, "force"],
                            ["sp_rop", s.setpoints.rop, "rop"],
                            ["ref_axial", s.reference.axial, "rop"],
                            ["ref_angular", s.reference.angular, "rotary_speed"]]) {
    const el = $(id);
    if (v === null || v === undefined || el.disabled || shown[id] === v) continue;
    if (document.activeElement === el) continue;
    el.value = +(v * factor(q)).toPrecision(5);
    shown[id] = v;
  }
}

function update(s) {
  units = s.units;
  if (Object.keys(charts).length === 0) makeCharts();
  fillControls(s);
  follow(s);
  $("model").textContent = s.model;
  const r = $("running");
  r.textContent = s.phase === "running" ? "running" : s.phase === "stopped" ? "stopped" : s.phase;
  r.className = "badge " + s.phase;
  const c = $("controller");
  c.textContent = s.controller_enabled ? "on" : "off";
  c.className = "badge " + (s.controller_enabled ? "good" : "bad");
  const opt = s.controllers.find(o => o.name === s.controller);
  $("ctrl_name").textContent = s.controller_enabled && opt ? "(" + opt.label + ")" : "";
  $("safe").textContent = s.safe_action ? "ACTIVE" : "no";
  $("time").textContent = fmt(s.signals.time);
  $("of_duration").textContent = s.duration ? " of " + s.duration : "";
  $("misses").textContent = s.stats.deadline_misses;
  $("missfrac").textContent = (100 * s.stats.deadline_misses / Math.max(s.stats.steps, 1)).toFixed(2);
  $("overruns").textContent = s.stats.overruns;
  $("late").textContent = s.stats.late_commands;
  $("rejected").textContent = s.stats.rejected_setpoints;
  $("sched").textContent = s.scheduler;
  $("error").textContent = s.error || "";
  let html = "";
  for (const [k, v] of Object.entries(s.signals))
    html += "<tr><td>" + k + "</td><td class='v' id='sig_" + k + "'>" + fmt(v) + "</td><td>" +
            (UNITS[k] || "") + "</td></tr>";
  $("signals").innerHTML = html;
  $("events").textContent = s.events.join("\n");
  ingest(s.trend, s.trend_reset);
}

function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.onmessage = ev => update(JSON.parse(ev.data));
  ws.onclose = () => setTimeout(connect, 1000);
}
connect();
