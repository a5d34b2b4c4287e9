// plcctl serve: the monitor page (service.md 12). Plain JavaScript, no library, no build
// step. Data: /api/profile once, /api/trend once, then the /api/stream events (status and
// samples at 10 Hz, the fault log and the counters when they change: nothing is polled,
// so nothing is older than the status). Tests read the state from the `data-*` attributes and
// `window.monitor`. The server's Content-Security-Policy allows no inline script or
// style attribute: styles are set through the CSSOM (`style.setProperty`).
"use strict";

const TREND_S = 60;
const $ = (id) => document.getElementById(id);

const monitor = {
  profile: { kind: "table", vars: {}, states: {}, counters: {}, lift: null, name: "" },
  columns: [],
  rows: [],            // trend rows (arrays in `columns` order), oldest first
  status: null,        // the last status event
  statusAt: 0,         // page clock (ms) when it arrived
  values: {},          // operand name -> value (D00, O00, A00, lcd0, Q04, ...)
  faults: null,        // the fault log (faults --json rows); null until the stream brings it
  doorCmdSince: null,  // wall-clock ms when the door command went on
  lastDir: 0,          // the lift's last travel direction seen (1 up, -1 down)
  paused: false,
  zoom: null,          // [t0, t1] in t_s, or null = the last 60 s
  serverLost: false,
  actionResult: "",    // the last action's answer ("stop: done", or the refusal), kept shown
};
window.monitor = monitor;

// ---------------------------------------------------------------- helpers
const pad = (n) => String(n).padStart(2, "0");
const opName = (kind, n) => kind + pad(n);
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}
async function getJson(path) {
  const r = await fetch(path, { cache: "no-store" });
  if (!r.ok) throw new Error(path + ": " + r.status);
  return r.json();
}
function val(op) {
  const v = monitor.values[op];
  return v === undefined ? null : v;
}
function nameOf(op) {
  for (const [name, o] of Object.entries(monitor.profile.vars)) if (o === op) return name;
  return null;
}
function tenths(v) { return (v / 10).toFixed(1); }

// ---------------------------------------------------------------- banner
function stateInfo() {
  const p = monitor.profile;
  const op = p.vars.state;
  if (!op) return null;
  const v = val(op);
  if (v === null) return null;
  return p.states[String(v)] || { text: "state " + v, level: "ok" };
}

/** [colour, title, detail] by service.md 12's first-match rules. */
function bannerOf(ev) {
  if (monitor.serverLost) return ["red", "no answer from the monitor", "plcctl serve is not running"];
  if (!ev || !ev.connected || !ev.status) return ["red", "no answer from the PLC", ev && ev.error ? ev.error : ""];
  const s = ev.status;
  const d = s.drive;
  const driveText = d ? `drive ${d.state.toUpperCase()} ${tenths(d.freq_dhz)} Hz ${d.reverse ? "REV" : "FWD"}` : "drive —";
  const title = `PLC ${s.plc.toUpperCase()} · ${driveText}`;
  const st = stateInfo();
  const stText = st ? st.text : "";
  if (s.link !== "Up") {
    const why = s.link === "Lost" ? "PLC-drive link lost" :
      `PLC-drive version mismatch (drive ${s.link.VersionMismatch.drive_version})`;
    return ["red", title, why];
  }
  if (d && d.fault) return ["red", title, `drive fault ${d.fault}: ${ev.drive_fault_text || ""}`];
  if (st && st.level === "fault") return ["red", title, stText];
  if (s.plc !== "Run") return ["orange", title, stText || "PLC not in RUN"];
  if (s.remote) return ["orange", title, (stText ? stText + " · " : "") + "remote service enabled"];
  if (s.warning) return ["orange", title, "warning: DIV0 at line " + s.warning.Div0.line];
  if (st && st.level === "warning") return ["orange", title, stText];
  return ["green", title, stText];
}

function renderBanner() {
  const [colour, title, detail] = bannerOf(monitor.status);
  const b = $("banner");
  b.dataset.colour = colour;
  $("banner-title").textContent = title;
  $("banner-detail").textContent = detail;
  // Actions (service.md 12): Stop always; Run, Ack, Clear log only with remote service.
  const ev = monitor.status;
  const up = !!(ev && ev.connected && ev.status && !monitor.serverLost);
  const remote = up && ev.status.remote;
  $("act-stop").disabled = !up;
  for (const id of ["act-run", "act-ack", "act-clear-faults"]) $(id).disabled = !remote;
  const why = !up ? "no PLC" :
    remote ? "" : "Run, Ack and Clear log need remote service: keys * 7 on the PLC";
  $("action-note").textContent = [monitor.actionResult, why].filter((t) => t).join(" · ");
}

// ---------------------------------------------------------------- age of the values
/** Values older than this are greyed out with their age. */
const STALE_MS = 2000;
/** How old the shown PLC values are (ms): the server's age when the status came plus the
 * time since, or null before the first. */
function valuesAge() {
  const ev = monitor.status;
  if (!ev || ev.age_ms === null || ev.age_ms === undefined) return null;
  return ev.age_ms + (Date.now() - monitor.statusAt);
}
function renderAge() {
  const age = valuesAge();
  const stale = age !== null && age > STALE_MS;
  for (const id of ["values-block", "mimic-block"]) $(id).dataset.stale = stale ? "1" : "0";
  $("values-age").textContent = stale ? `values ${(age / 1000).toFixed(1)} s old` : "";
}

// ---------------------------------------------------------------- live values
function lampsInto(box, kind, count, bits) {
  if (box.childElementCount !== count) {
    box.textContent = "";
    for (let n = 0; n < count; n++) {
      const op = opName(kind, n);
      const name = nameOf(op);
      box.appendChild(el("div", { class: "lamp", "data-op": op, title: op }, name ? `${op} ${name}` : op));
    }
  }
  for (let n = 0; n < count; n++) box.children[n].dataset.on = (bits >> n) & 1 ? "1" : "0";
}
function kvInto(box, pairs) {
  box.textContent = "";
  for (const [k, v] of pairs) {
    box.appendChild(el("div", { class: "k" }, k));
    box.appendChild(el("div", { class: "v" }, v));
  }
}
function renderValues() {
  const ev = monitor.status;
  const s = ev && ev.status;
  if (!s) return;
  const d = s.drive;
  kvInto($("drive-values"), [
    ["FRQ", d ? `${tenths(d.freq_dhz)} Hz ${d.reverse ? "REV" : "FWD"}` : "—"],
    ["UDC", d ? `${tenths(d.udc_dv)} V` : "—"],
    ["IMX", d ? `${(d.imax_ca / 100).toFixed(2)} A` : "—"],
    ["COM", d ? String(d.com) : "—"],
    ["drive", d ? `${d.state.toUpperCase()}, fault ${d.fault}` : "link not up"],
  ]);
  lampsInto($("lamps-d"), "D", 16, s.d);
  lampsInto($("lamps-o"), "O", 8, s.o);
  const analog = s.a.map((v, n) => {
    const op = opName("A", n);
    const name = nameOf(op);
    return [name ? `${op} ${name}` : op, String(v)];
  });
  s.lcd.forEach((v, n) => {
    const op = "lcd" + n;
    const name = nameOf(op);
    analog.push([name ? `${op} ${name}` : op, v === null ? "—" : String(v)]);
  });
  kvInto($("analog"), analog);
  const rows = Array.isArray(ev.lcd_text) ? ev.lcd_text : null;
  $("lcd").textContent = rows ? rows.join("\n") : "—";
  const id = ev.identity || {};
  kvInto($("plc-values"), [
    ["state", `${s.plc.toUpperCase()}${s.remote ? ", remote service ON" : ""}`],
    ["slot", s.slot === null ? "—" : String(s.slot) + (s.unsaved ? " (unsaved edits)" : "")],
    ["scan", `${s.scan_last_us} µs (max ${s.scan_max_us} µs)`],
    ["uptime", `${(s.uptime_ms / 1000).toFixed(1)} s`],
    ["firmware", `${id.firmware || "?"} (${id.git || "?"})`],
    ["service version", String(ev.service_version)],
  ]);
}

// ---------------------------------------------------------------- mimic / table
const SVG = "http://www.w3.org/2000/svg";
function svg(tag, attrs, text) {
  const e = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}
const LOAD_TEXT = ["unloaded", "loaded", "full", "overloaded"];

function doorState() {
  const p = monitor.profile, l = p.lift;
  const st = val(p.vars.state);
  if (st !== null && l.door_fault_states.includes(st)) return "fault";
  if (val(p.vars.door_closed) === 1) return "closed";
  const cmd = val(p.vars.door_open_cmd) === 1;
  if (cmd && monitor.doorCmdSince !== null &&
      Date.now() - monitor.doorCmdSince >= l.door_stroke_s * 1000) return "open";
  return "partly";
}

function renderLift() {
  const p = monitor.profile, l = p.lift, v = p.vars;
  const box = $("mimic");
  const N = l.floors, H = 90, top = 20, w = 260;
  const floor = val(v.floor), target = val(v.target);
  const up = val(v.up) === 1, down = val(v.down) === 1;
  const moving = up || down;
  const door = doorState();
  const load = val(v.load);
  const y = (f) => top + (N - f) * H;  // top edge of floor f's band
  if (moving) monitor.lastDir = up ? 1 : -1;
  // Level at `floor` only while every level input (the vanes) is on; without level
  // inputs in the profile, while not moving.
  const levelIns = l.level_inputs || [];
  const level = levelIns.length > 0 ? levelIns.every((op) => val(op) === 1) : !moving;
  // Between floors while moving or stopped off level (a trip mid-shaft): half a floor
  // towards the travel direction, else towards the target, else the last direction seen.
  let pos = floor >= 1 ? floor : 1;
  if (floor >= 1 && (moving || !level)) {
    let dir = moving ? (up ? 1 : -1) : 0;
    if (dir === 0 && target !== null && target >= 1 && target !== floor) dir = target > floor ? 1 : -1;
    if (dir === 0) dir = monitor.lastDir || (floor < N ? 1 : -1);
    if ((floor === N && dir > 0) || (floor === 1 && dir < 0)) dir = -dir;
    pos = floor + dir * 0.5;
  }
  box.dataset.floor = floor === null ? "" : String(floor);
  box.dataset.target = target === null ? "" : String(target);
  box.dataset.door = door;
  box.dataset.moving = moving ? (up ? "up" : "down") : "";
  box.dataset.pos = String(pos);
  box.dataset.level = level ? "1" : "0";
  const s = svg("svg", { viewBox: `0 0 ${w} ${N * H + 2 * top}`, role: "img" });
  s.appendChild(svg("rect", { x: 70, y: top, width: 110, height: N * H, fill: "#eceff1", stroke: "#90a4ae" }));
  for (let f = 1; f <= N; f++) {
    const fy = y(f);
    s.appendChild(svg("line", { x1: 70, x2: 180, y1: fy + H, y2: fy + H, stroke: "#b0bec5" }));
    s.appendChild(svg("text", { x: 190, y: fy + H - 8, "font-size": 16, fill: "#37474f" }, String(f)));
    const btn = l.call_buttons[f - 1];
    const lit = btn && val(btn) === 1;
    s.appendChild(svg("circle", {
      cx: 40, cy: fy + H / 2, r: 9, fill: lit ? "#fbbc04" : "#dadce0", stroke: "#0003",
      "data-call": String(f), "data-on": lit ? "1" : "0",
    }));
    if (target === f) {
      s.appendChild(svg("polygon", {
        points: `${215},${fy + H / 2} ${235},${fy + H / 2 - 10} ${235},${fy + H / 2 + 10}`,
        fill: "#1a73e8", "data-target-mark": String(f),
      }));
    }
  }
  const cy = y(pos) + 6, ch = H - 12;
  const known = floor !== null && floor >= 1;
  const car = svg("g", { "data-car": "" });
  car.appendChild(svg("rect", { x: 80, y: cy, width: 90, height: ch, rx: 4,
    fill: known ? "#ffffff" : "#cfd8dc", stroke: "#263238", "stroke-width": 2 }));
  // The door: two leaves, the gap by its state (004's four states).
  const gap = { closed: 0, partly: 22, open: 56, fault: 22 }[door];
  const leaf = (70 - gap) / 2;
  const doorColour = door === "fault" ? "#c5221f" : "#78909c";
  car.appendChild(svg("rect", { x: 90, y: cy + 8, width: leaf, height: ch - 16, fill: doorColour }));
  car.appendChild(svg("rect", { x: 160 - leaf, y: cy + 8, width: leaf, height: ch - 16, fill: doorColour }));
  if (moving) {
    car.appendChild(svg("text", { x: 125, y: cy + ch / 2 + 8, "font-size": 26, "text-anchor": "middle",
      fill: "#1a73e8" }, up ? "▲" : "▼"));
  }
  if (load !== null) {
    const lw = Math.min(3, Math.max(0, load)) / 3 * 86;
    car.appendChild(svg("rect", { x: 82, y: cy + ch - 6, width: lw, height: 4,
      fill: load >= 3 ? "#c5221f" : load >= 2 ? "#e37400" : "#1e8e3e" }));
  }
  s.appendChild(car);
  box.textContent = "";
  const row = el("div", { class: "mimic-row" });
  row.appendChild(s);
  row.appendChild(carPanel(known ? floor : null, up, down, target));
  box.appendChild(row);
  const st = stateInfo();
  box.appendChild(el("div", { class: "mimic-info" },
    `floor ${known ? floor : "unknown"}${known && !level && !moving ? " (stopped between floors)" : ""} · target ${target || "—"} · door ${door} · ` +
    `load ${load === null ? "—" : LOAD_TEXT[load] || load}${st ? " · " + st.text : ""}`));
}

/** The car's panel (004 §2.7.1, right of the car): the floor display with the travel
 * direction and the target, the floor buttons (`call_buttons`), then the elements of
 * `[lift.car_panel]` the lift has (alarm, its bell, door open, priority key, STOP), each
 * lit while its bit is 1. An element the profile does not name is not drawn. */
const PANEL_ITEMS = [
  ["door_open", "◀ ▶", "door open"],
  ["alarm", "ALARM", "alarm"],
  ["alarm_bell", "bell", "alarm bell ringing"],
  ["priority_key", "KEY", "priority key"],
  ["stop", "STOP", "in-car STOP"],
];
function carPanel(floor, up, down, target) {
  const l = monitor.profile.lift;
  const items = l.car_panel || {};
  const panel = el("div", { class: "car-panel", "data-car-panel": "" });
  const arrow = up ? "▲" : down ? "▼" : "";
  const disp = el("div", { class: "panel-display", "data-panel": "display" });
  disp.appendChild(el("span", { class: "panel-floor" }, floor === null ? "–" : String(floor)));
  disp.appendChild(el("span", { class: "panel-arrow" }, arrow));
  disp.appendChild(el("div", { class: "panel-target" },
    target !== null && target >= 1 && target !== floor ? `→ ${target}` : ""));
  panel.appendChild(disp);
  const lamp = (key, label, title, op) => {
    const on = op ? val(op) === 1 : false;
    const name = op ? nameOf(op) : null;
    return el("div", {
      class: "pbtn", "data-panel": key, "data-on": on ? "1" : "0",
      title: op ? `${title}: ${op}${name ? " " + name : ""}` : title,
    }, label);
  };
  const floors = el("div", { class: "panel-floors" });
  for (let f = l.floors; f >= 1; f--) floors.appendChild(lamp("floor-" + f, String(f), "floor " + f, l.call_buttons[f - 1]));
  panel.appendChild(floors);
  for (const [key, label, title] of PANEL_ITEMS) {
    if (items[key]) panel.appendChild(lamp(key, label, title, items[key]));
  }
  return panel;
}

function renderTable() {
  const p = monitor.profile;
  let entries = Object.entries(p.vars);
  if (entries.length === 0) {
    entries = monitor.columns.filter((c) => /^Q\d\d$/.test(c)).map((c) => [c, c]);
  }
  const t = el("table", { "data-table": "" });
  const head = el("tr");
  for (const h of ["name", "variable", "value"]) head.appendChild(el("th", {}, h));
  t.appendChild(head);
  for (const [name, op] of entries) {
    const tr = el("tr", { "data-op": op });
    const v = val(op);
    tr.appendChild(el("td", {}, name));
    tr.appendChild(el("td", {}, op));
    tr.appendChild(el("td", {}, v === null ? "—" : String(v)));
    t.appendChild(tr);
  }
  $("mimic").textContent = "";
  $("mimic").appendChild(t);
}

function renderMimic() {
  if (monitor.profile.kind === "lift" && monitor.profile.lift) renderLift();
  else renderTable();
}

// ---------------------------------------------------------------- trend
const COLOURS = ["#1a73e8", "#e37400", "#188038", "#a142f4", "#d01884", "#12b5cb", "#5f6368", "#b06000", "#3c4043", "#9aa0a6"];
function series() {
  const c = monitor.columns;
  const idx = (name) => c.indexOf(name);
  const f = idx("f_cmd_hz"), dir = idx("dir"), u = idx("u_dc_v");
  const top = [
    { label: "f_cmd_hz × dir (Hz)", unit: "Hz", get: (r) => (r[f] === null ? null : r[f] * (r[dir] || 1)) },
    { label: "u_dc_v (V)", unit: "V", get: (r) => r[u] },
  ];
  const named = Object.entries(monitor.profile.vars).filter(([, o]) => /^Q\d\d$/.test(o));
  const qs = named.length ? named.map(([n, o]) => [`${o} ${n}`, o]) :
    c.filter((x) => /^Q\d\d$/.test(x)).map((o) => [o, o]);
  // Q variables are the program's integers (floors, states, setpoints): no unit.
  const qser = qs.filter(([, o]) => idx(o) >= 0).map(([label, o]) => ({ label, unit: "", get: (r) => r[idx(o)] }));
  // Codes and counts (a floor, a state: 0..31 in the window) in one pane, larger
  // values (a setpoint) in another, so that neither flattens the other.
  const rows = visibleRows();
  const small = (s) => rows.every((r) => { const v = s.get(r); return v === null || (v >= -31 && v <= 31); });
  return [top, qser.filter(small), qser.filter((s) => !small(s))].filter((p) => p.length);
}
function visibleRows() {
  const rows = monitor.rows;
  if (!rows.length) return [];
  const [t0, t1] = viewWindow();
  return rows.filter((r) => r[0] >= t0 && r[0] <= t1);
}
function viewWindow() {
  if (monitor.zoom) return monitor.zoom;
  const last = monitor.rows.length ? monitor.rows[monitor.rows.length - 1][0] : 0;
  return [last - TREND_S, last];
}
/** About `n` round values covering lo..hi (1, 2 or 5 times a power of ten apart). */
function niceTicks(lo, hi, n) {
  const raw = (hi - lo) / Math.max(1, n);
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw) || 10 * p;
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(v);
  return { step, ticks: out };
}
/** A tick's text: as many decimals as the step needs, never "-0". */
function tickText(v, step) {
  const d = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  const t = v.toFixed(d);
  return /^-0(\.0*)?$/.test(t) ? t.slice(1) : t;
}
function drawTrend() {
  const cv = $("trend");
  const dpr = window.devicePixelRatio || 1;
  const W = cv.clientWidth, Hh = cv.clientHeight;
  if (cv.width !== Math.round(W * dpr)) { cv.width = Math.round(W * dpr); cv.height = Math.round(Hh * dpr); }
  const g = cv.getContext("2d");
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, W, Hh);
  const rows = visibleRows();
  cv.dataset.samples = String(rows.length);
  cv.dataset.span = rows.length ? (rows[rows.length - 1][0] - rows[0][0]).toFixed(1) : "0";
  const [t0, t1] = viewWindow();
  const panes = series();
  const legend = $("trend-legend");
  legend.textContent = "";
  const L = 48, R = 8, gap = 18, B = 22;
  const paneH = (Hh - B - gap * panes.length) / panes.length;
  const allTicks = [];
  let colourAt = 0;
  panes.forEach((ser, p) => {
    const py = 6 + p * (paneH + gap);
    let lo = Infinity, hi = -Infinity;
    for (const s of ser) for (const r of rows) {
      const v = s.get(r);
      if (v !== null && v !== undefined) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    }
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi - lo < 1e-9) { hi += 1; lo -= 1; }
    const x = (t) => L + (t - t0) / Math.max(1e-9, t1 - t0) * (W - L - R);
    const y = (v) => py + paneH - (v - lo) / (hi - lo) * paneH;
    g.strokeStyle = "#dadce0"; g.lineWidth = 1;
    g.strokeRect(L, py, W - L - R, paneH);
    g.fillStyle = "#5f6368"; g.font = "11px system-ui, sans-serif";
    // Value ticks with grid lines; the pane's units in its corner.
    const vt = niceTicks(lo, hi, Math.max(3, Math.floor(paneH / 30)));
    for (const v of vt.ticks) {
      const yy = y(v);
      g.strokeStyle = "#f1f3f4"; g.beginPath(); g.moveTo(L, yy); g.lineTo(W - R, yy); g.stroke();
      g.fillText(tickText(v, vt.step), 2, Math.min(py + paneH, Math.max(py + 10, yy + 4)));
    }
    const units = [...new Set(ser.map((s) => s.unit).filter((u) => u))].join(", ");
    if (units) g.fillText(units, L + 4, py + 12);
    allTicks.push(units || "-");
    ser.forEach((s, k) => {
      const colour = COLOURS[(colourAt + k) % COLOURS.length];
      g.strokeStyle = colour; g.lineWidth = 1.5; g.beginPath();
      let pen = false;
      for (const r of rows) {
        const v = s.get(r);
        if (v === null || v === undefined) { pen = false; continue; }
        if (pen) g.lineTo(x(r[0]), y(v)); else { g.moveTo(x(r[0]), y(v)); pen = true; }
      }
      g.stroke();
      const item = el("span", {}, s.label);
      item.style.setProperty("--c", colour);
      legend.appendChild(item);
    });
    colourAt += ser.length;
  });
  // Time ticks on the PLC's uptime (t_s), the newest sample at the right.
  const span = Math.max(1e-9, t1 - t0);
  const tt = niceTicks(t0, t1, Math.max(2, Math.floor((W - L - R) / 90)));
  const tx = (t) => L + (t - t0) / span * (W - L - R);
  const axisY = Hh - B + 4;
  g.fillStyle = "#5f6368"; g.font = "11px system-ui, sans-serif"; g.textAlign = "center";
  const timeTicks = [];
  for (const t of tt.ticks) {
    const xx = tx(t);
    g.strokeStyle = "#dadce0"; g.beginPath(); g.moveTo(xx, axisY - 4); g.lineTo(xx, axisY); g.stroke();
    const text = tickText(t, tt.step) + " s";
    g.fillText(text, xx, axisY + 12);
    timeTicks.push(text);
  }
  g.textAlign = "left";
  cv.dataset.timeTicks = timeTicks.join("|");
  cv.dataset.units = allTicks.join("|");
  legend.appendChild(el("span", { class: "window" },
    `time: PLC uptime t_s ${t0.toFixed(1)} … ${t1.toFixed(1)} s${monitor.paused ? " (paused)" : ""}`));
  if (drag) {
    g.fillStyle = "#1a73e833";
    g.fillRect(Math.min(drag.x0, drag.x1), 0, Math.abs(drag.x1 - drag.x0), Hh);
  }
}
let drag = null;
function tOfX(xpx) {
  const cv = $("trend");
  const [t0, t1] = viewWindow();
  const L = 48, R = 8;
  return t0 + (xpx - L) / (cv.clientWidth - L - R) * (t1 - t0);
}
function setupTrend() {
  const cv = $("trend");
  cv.addEventListener("mousedown", (e) => { drag = { x0: e.offsetX, x1: e.offsetX }; });
  cv.addEventListener("mousemove", (e) => { if (drag) { drag.x1 = e.offsetX; drawTrend(); } });
  window.addEventListener("mouseup", () => {
    if (!drag) return;
    const a = tOfX(Math.min(drag.x0, drag.x1)), b = tOfX(Math.max(drag.x0, drag.x1));
    drag = null;
    if (b - a > 0.05) { monitor.zoom = [a, b]; monitor.paused = true; $("trend-pause").textContent = "Resume"; }
    drawTrend();
  });
  $("trend-pause").addEventListener("click", () => {
    monitor.paused = !monitor.paused;
    $("trend-pause").textContent = monitor.paused ? "Resume" : "Pause";
    if (!monitor.paused) monitor.zoom = null;
    drawTrend();
  });
  $("trend-reset").addEventListener("click", () => {
    monitor.zoom = null; monitor.paused = false; $("trend-pause").textContent = "Pause"; drawTrend();
  });
  $("trend-csv").addEventListener("click", () => download("trend.csv", trendCsv()));
}
/** The visible window as CSV with hil-sim's column names and number formats. */
function trendCsv() {
  const c = monitor.columns;
  const fmt = (name, v) => {
    if (v === null || v === undefined) return "";
    if (name === "t_s") return v.toFixed(6);
    if (name === "u_dc_v") return v.toFixed(3);
    if (name === "f_cmd_hz") return v.toFixed(1);
    if (name === "imx_a") return v.toFixed(2);
    return String(v);
  };
  const lines = [c.join(",")];
  for (const r of visibleRows()) lines.push(r.map((v, i) => fmt(c[i], v)).join(","));
  return lines.join("\n") + "\n";
}
function download(name, text) {
  const a = el("a", { href: URL.createObjectURL(new Blob([text], { type: "text/csv" })), download: name });
  document.body.appendChild(a); a.click(); a.remove();
}

// ---------------------------------------------------------------- faults, counters
function splitTime(t) {
  const m = /^(\d{4}-\d\d-\d\d) (\d\d:\d\d:\d\d)$/.exec(t);
  return m ? [m[1], m[2]] : ["", t];
}
// The PLC's time of day; without it "clock not set" and the host's estimate (~).
function entryTime(f) {
  if (f.wall_s !== null && f.wall_s !== undefined) return splitTime(f.time);
  return [f.time, "~" + splitTime(f.host_time)[1]];
}
function renderFaults() {
  if (monitor.faults === null) return;
  const body = $("faults").tBodies[0];
  body.textContent = "";
  const names = monitor.profile.log_values || ["lcd0", "lcd1"];
  $("faults-v0").textContent = names[0]; $("faults-v1").textContent = names[1];
  for (const f of monitor.faults) {
    const [date, time] = entryTime(f);
    const values = (f.values || [null, null]).map((v) => (v === null ? "" : String(v)));
    const tr = el("tr", { "data-pos": String(f.pos), "data-code": String(f.code) });
    for (const v of [date, time, String(f.code), f.text, ...values]) tr.appendChild(el("td", {}, v));
    body.appendChild(tr);
  }
  if (!monitor.faults.length) {
    const tr = el("tr"); tr.appendChild(el("td", { colspan: "6" }, "fault log empty")); body.appendChild(tr);
  }
}
function faultsCsv() {
  const q = (s) => (/[",\n]/.test(s) ? `"${s.replace(/"/g, '""')}"` : s);
  const names = monitor.profile.log_values || ["lcd0", "lcd1"];
  const lines = ["pos,time,wall_s,host_time,power_up,uptime_s,code,name,text," + names.map(q).join(",")];
  const opt = (v) => (v === null || v === undefined ? "" : String(v));
  for (const f of monitor.faults || []) {
    const values = (f.values || [null, null]).map(opt);
    lines.push([f.pos, q(f.time), opt(f.wall_s), q(f.host_time), f.power_up, f.uptime_s, f.code, f.name,
      q(f.text), ...values].join(","));
  }
  return lines.join("\n") + "\n";
}
function renderCounters(k) {
  const box = $("counters");
  // A PLC without counters (or before the first read) refuses GetCounters: say so.
  if (!k || k.error) {
    box.dataset.available = "0";
    kvInto(box, [["counters", k && k.error ? `not available (PLC: ${k.error})` : "not read yet"]]);
    return;
  }
  box.dataset.available = "1";
  const pairs = [
    ["RUN starts", k.run_starts], ["minutes in RUN", k.run_minutes], ["minutes PWM on", k.pwm_minutes],
    ["link errors", k.link_errors], ["program saves", k.program_saves], ["power-ups", k.power_ups],
  ].map(([a, b]) => [a, String(b)]);
  (k.trips || []).forEach((n, i) => { if (n) pairs.push([`trips code ${i + 1}`, String(n)]); });
  const names = {};
  for (const [name, op] of Object.entries(monitor.profile.counters)) names[op] = name;
  (k.app || []).forEach((n, i) => {
    const op = "Q" + (60 + i);
    pairs.push([names[op] ? `${names[op]} (${op})` : `app counter ${i + 1} (${op})`, String(n)]);
  });
  kvInto(box, pairs);
}

// ---------------------------------------------------------------- actions
function confirmBox(text) {
  return new Promise((resolve) => {
    $("confirm-text").textContent = text;
    $("confirm").hidden = false;
    const done = (ok) => { $("confirm").hidden = true; resolve(ok); };
    $("confirm-yes").onclick = () => done(true);
    $("confirm-no").onclick = () => done(false);
  });
}
/** What a STOP means for the application (a STOP from here needs no keypad consent). */
function stopWords() {
  const again = "Only the PLC's keypad can start RUN again (RUN there, or * 7 for remote " +
    "service and then Run here).";
  if (monitor.profile.kind === "lift") {
    return "Stop the PLC? The program stops at once and every output goes off: the lift " +
      "stops where it is, also between floors, with the brake on; anyone in the car stays " +
      "there until RUN. " + again;
  }
  return "Stop the PLC? The program stops at once and every output goes off: the machine " +
    "stops wherever it is. " + again;
}
async function act(action) {
  const words = { stop: stopWords(), run: "Start RUN?", ack: "Acknowledge the drive fault?",
    "clear-faults": "Erase the fault log?" };
  if (!(await confirmBox(words[action]))) return;
  monitor.actionResult = action + "…";
  renderBanner();
  try {
    const r = await fetch("/api/" + action, { method: "POST", headers: { "Content-Type": "application/json" }, body: "{}" });
    const body = await r.json().catch(() => ({}));
    monitor.actionResult = r.ok ? action + ": done" : action + ": " + (body.error || r.status);
  } catch (e) {
    monitor.actionResult = action + ": no answer from the monitor";
  }
  renderBanner();
}

// ---------------------------------------------------------------- data flow
function onStatus(ev) {
  monitor.status = ev;
  monitor.statusAt = Date.now();
  const s = ev.status;
  if (ev.connected && s) {
    for (let n = 0; n < 16; n++) monitor.values[opName("D", n)] = (s.d >> n) & 1;
    for (let n = 0; n < 8; n++) monitor.values[opName("O", n)] = (s.o >> n) & 1;
    s.a.forEach((v, n) => { monitor.values[opName("A", n)] = v; });
    s.lcd.forEach((v, n) => { monitor.values["lcd" + n] = v; });
  }
  trackDoor();
  renderBanner();
  renderValues();
  renderMimic();
  renderAge();
}
function onSample(row) {
  monitor.rows.push(row);
  const newest = row[0];
  while (monitor.rows.length && monitor.rows[0][0] < newest - 600) monitor.rows.shift();
  monitor.columns.forEach((c, i) => { if (/^Q\d\d$/.test(c)) monitor.values[c] = row[i]; });
}
function trackDoor() {
  const v = monitor.profile.vars;
  if (!v.door_open_cmd) return;
  const on = val(v.door_open_cmd) === 1;
  if (on && monitor.doorCmdSince === null) monitor.doorCmdSince = Date.now();
  if (!on) monitor.doorCmdSince = null;
}

async function start() {
  // The token came in the URL once; the cookie carries it from now on.
  if (location.search.includes("token=")) history.replaceState(null, "", "/");
  try { monitor.profile = await getJson("/api/profile"); } catch (e) { /* a table */ }
  if (monitor.profile.name) document.title = monitor.profile.name + " · PLC monitor";
  $("mimic-title").textContent = monitor.profile.kind === "lift" ? (monitor.profile.name || "Lift") :
    (monitor.profile.name || "Variables");
  try {
    const t = await getJson("/api/trend?s=" + TREND_S);
    monitor.columns = t.columns;
    t.rows.forEach(onSample);
  } catch (e) { /* the stream fills it */ }
  try { onStatus(await getJson("/api/status")); } catch (e) { renderBanner(); }
  setupTrend();
  for (const b of document.querySelectorAll("[data-action]")) b.addEventListener("click", () => act(b.dataset.action));
  $("faults-csv").addEventListener("click", () => download("faults.csv", faultsCsv()));
  const es = new EventSource("/api/stream");
  es.addEventListener("status", (e) => { monitor.serverLost = false; onStatus(JSON.parse(e.data)); });
  es.addEventListener("sample", (e) => { onSample(JSON.parse(e.data).row); });
  es.addEventListener("counters", (e) => { renderCounters(JSON.parse(e.data)); });
  es.addEventListener("faults", (e) => { monitor.faults = JSON.parse(e.data); renderFaults(); });
  es.addEventListener("error", () => { monitor.serverLost = true; renderBanner(); });
  es.addEventListener("open", () => { monitor.serverLost = false; });
  renderCounters(null);
  // Redraw at 10 Hz (the door's stroke time and the values' age run on the page's clock).
  setInterval(() => {
    renderAge();
    if (!monitor.paused) drawTrend();
    if (monitor.profile.kind === "lift") { trackDoor(); renderMimic(); }
  }, 100);
  drawTrend();
}
start();
