// The operator display's page: one WebSocket to the operator_display node; the state
// arrives as JSON text, each camera view as a binary message (17 header bytes, then the
// JPEG). What the page has drawn is kept in window.teleopDisplay (the browser test
// reads it).
"use strict";

const CAMERAS = ["top", "side"];
const HEADER_LEN = 17;
const FINGER_NAMES = { ff: "first", mf: "middle", rf: "ring", lf: "little", th: "thumb" };

const seen = {
  connected: false,
  states: 0,
  forceUpdates: 0,
  lastForces: [],
  frames: { top: 0, side: 0 },
  framesDroppedHere: { top: 0, side: 0 },
  decoded: { top: { width: 0, height: 0 }, side: { width: 0, height: 0 } },
  nodes: {},
  lastState: null,
};
window.teleopDisplay = seen;

const $ = (id) => document.getElementById(id);
const fmt = (x, digits) => (x === null || x === undefined || !isFinite(x)) ? "-" : x.toFixed(digits);

// ---- camera views: decode the newest only; a frame that comes while one is being
// decoded replaces the waiting one (counted), so a slow machine shows fewer frames.
const views = {};
for (const name of CAMERAS) {
  views[name] = { img: $("view-" + name), busy: false, waiting: null, url: null };
  views[name].img.addEventListener("load", () => onDecoded(name));
  views[name].img.addEventListener("error", () => onDecoded(name));
}

function showFrame(name, blob) {
  const v = views[name];
  if (v.busy) {
    if (v.waiting) seen.framesDroppedHere[name] += 1;
    v.waiting = blob;
    return;
  }
  v.busy = true;
  const url = URL.createObjectURL(blob);
  if (v.url) URL.revokeObjectURL(v.url);
  v.url = url;
  v.img.src = url;
}

function onDecoded(name) {
  const v = views[name];
  v.busy = false;
  seen.decoded[name] = { width: v.img.naturalWidth, height: v.img.naturalHeight };
  if (v.waiting) {
    const next = v.waiting;
    v.waiting = null;
    showFrame(name, next);
  }
}

function onBinary(buf) {
  if (buf.byteLength <= HEADER_LEN) return;
  const dv = new DataView(buf);
  const name = CAMERAS[dv.getUint8(0)];
  if (!name) return;
  seen.frames[name] += 1;
  showFrame(name, new Blob([buf.slice(HEADER_LEN)], { type: "image/jpeg" }));
}

// ---- fingertip forces: five bars on one scale, a dashed line at each finger's peak.
let forceScale = null;
function buildForceBars(fingers, scaleN) {
  forceScale = scaleN;
  const scale = $("force-scale");
  scale.textContent = "";
  const steps = 5;
  for (let i = 0; i <= steps; i++) {
    const s = document.createElement("span");
    s.style.bottom = (100 * i / steps) + "%";
    s.textContent = (scaleN * i / steps).toFixed(0) + (i === steps ? " N" : "");
    scale.appendChild(s);
  }
  const bars = $("force-bars");
  bars.textContent = "";
  for (const f of fingers) {
    const d = document.createElement("div");
    d.className = "finger";
    d.id = "finger-" + f;
    d.innerHTML = '<div class="fill"></div><div class="peak"></div><div class="value"></div>' +
      '<div class="label">' + f + ' <span class="dim">(' + (FINGER_NAMES[f] || f) + ')</span></div>';
    bars.appendChild(d);
  }
}

function drawForces(forces) {
  if (forceScale !== forces.scale_n) buildForceBars(forces.fingers, forces.scale_n);
  $("forces-info").textContent = forces.received === 0 ? "(none received yet)"
    : "newest " + fmt(forces.age_ms, 0) + " ms ago, scale 0-" + forces.scale_n + " N";
  if (forces.newton.length !== forces.fingers.length) return;
  forces.fingers.forEach((f, i) => {
    const el = $("finger-" + f);
    const n = forces.newton[i];
    const frac = Math.max(0, Math.min(1, n / forces.scale_n));
    const fill = el.querySelector(".fill");
    fill.style.height = (100 * frac) + "%";
    fill.classList.toggle("high", n > 0.8 * forces.scale_n);
    el.querySelector(".peak").style.bottom = (100 * Math.min(1, forces.peak_newton[i] / forces.scale_n)) + "%";
    const value = el.querySelector(".value");
    value.textContent = fmt(n, 1) + " N";
    value.style.bottom = "calc(" + (100 * frac) + "% + 2px)";
  });
  if (forces.received !== seen.forcesReceived) {
    seen.forcesReceived = forces.received;
    seen.forceUpdates += 1;
    seen.lastForces = forces.newton.slice();
  }
}

// ---- tables
function fillRows(tbody, rows) {
  while (tbody.rows.length > rows.length) tbody.deleteRow(-1);
  rows.forEach((cells, r) => {
    const row = tbody.rows[r] || tbody.insertRow();
    while (row.cells.length > cells.length) row.deleteCell(-1);
    cells.forEach((c, i) => {
      const cell = row.cells[i] || row.insertCell();
      const text = typeof c === "object" ? c.text : c;
      const cls = typeof c === "object" ? c.cls : (typeof c === "number" ? "num" : "");
      if (cell.textContent !== String(text)) cell.textContent = text;
      if (cell.className !== cls) cell.className = cls;
    });
  });
}

const num = (x, d) => ({ text: fmt(x, d), cls: "num" });

function drawJoints(which, joints) {
  const info = $(which + "-info");
  const tbody = $(which + "-table").tBodies[0];
  if (!joints) { info.textContent = "(none received yet)"; fillRows(tbody, []); return; }
  info.textContent = "newest " + fmt(joints.age_ms, 0) + " ms ago";
  if (which === "pr2") {
    fillRows(tbody, joints.name.map((n, i) => [n, num(joints.position[i], 3),
      num(joints.velocity[i], 3), num(joints.effort[i], 2)]));
  } else {
    const rows = [];
    const half = Math.ceil(joints.name.length / 2);
    for (let i = 0; i < half; i++) {
      const j = i + half;
      rows.push([joints.name[i], num(joints.position[i], 3),
        j < joints.name.length ? joints.name[j] : "", j < joints.name.length ? num(joints.position[j], 3) : ""]);
    }
    fillRows(tbody, rows);
  }
}

function pill(id, on, text, cls) {
  const el = $(id);
  el.className = "pill " + (cls || (on ? "on" : "off"));
  if (text !== undefined) el.textContent = text;
}

function nodeState(s, name) {
  const n = s.nodes.find((x) => x.name === name);
  return n ? n.state : "unseen";
}

function stateClass(state) {
  return { active: "on", inactive: "off", fault: "bad", silent: "bad", unseen: "warn" }[state] || "warn";
}

function draw(s) {
  if (!s.views) return; // the node has not taken its first period yet
  seen.states += 1;
  seen.lastState = s;
  $("clock").textContent = "display time " + new Date(s.t_s * 1000).toISOString().slice(11, 23);
  for (const v of s.views) {
    $("view-" + v.name + "-info").textContent = v.received === 0 ? "(no view yet)" :
      fmt(v.rate_hz, 1) + " Hz, " + fmt(v.age_ms, 0) + " ms old on arrival" +
      (v.refused ? ", " + v.refused + " refused" : "");
  }
  drawForces(s.forces);
  drawJoints("pr2", s.pr2);
  drawJoints("shadow", s.shadow);
  const op = s.operator;
  pill("enable", op && op.enable, "enable");
  pill("clutch", op && op.clutch, "clutch");
  pill("camstop", op && op.camera_stop, "camera stop", op && op.camera_stop ? "warn" : "off");
  pill("scale", true, "scale " + (op ? fmt(op.motion_scale, 2) : "-"), "info");
  const arm = nodeState(s, "pr2_arm_controller");
  const hand = nodeState(s, "shadow_hand_controller");
  pill("arm", false, "arm " + arm, stateClass(arm));
  pill("hand", false, "hand " + hand, stateClass(hand));
  for (const n of s.nodes) seen.nodes[n.name] = n.state;
  fillRows($("node-table").tBodies[0], s.nodes.map((n) => [
    n.name, n.site + (n.machine ? " (" + n.machine + ")" : ""),
    { text: n.state, cls: "state-" + n.state }, num(n.age_s, 1),
    { text: n.alerts.map((a) => a[0] + " " + a[1]).join(", "), cls: "err" },
    // An error whose cause is gone reads "recovered at HH:MM:SS UTC: ..." and is muted.
    { text: n.last_error, cls: n.last_error.startsWith("recovered at ") ? "recovered" : "err" }]));
  fillRows($("topic-table").tBodies[0], s.topics.map((t) => [
    t.name, num(t.rate_hz, 1), num(t.nominal_hz, 1), num(t.latency_p50_ms, 2),
    num(t.latency_p99_ms, 2), num(t.refused, 0), num(t.accepted, 0)]));
  $("web-info").textContent = "(page: " + s.web.clients + " browser(s), " + s.web.frames_sent +
    " views sent, " + s.web.frames_skipped + " skipped for slow browsers)";
}

// ---- the socket, reconnecting every second while the node is away
function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.binaryType = "arraybuffer";
  ws.onopen = () => { seen.connected = true; pill("link", true, "connected"); };
  ws.onclose = () => {
    seen.connected = false;
    pill("link", false, "disconnected: retrying", "bad");
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === "string") {
      try { draw(JSON.parse(ev.data)); } catch (e) { console.error("state", e); }
    } else {
      onBinary(ev.data);
    }
  };
}
connect();
