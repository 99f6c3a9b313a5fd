// Shared by both review pages (tracks: app.js, trim: trim.js): DOM lookup, the JSON API, the
// state line, the playhead, row selection and the editing keys. Each page script defines the
// globals these use: `state` (rows, selected, fps, duration, dirty) and `renderAll()`.
"use strict";

const $ = (sel) => document.querySelector(sel);

async function api(path, options) {
  const res = await fetch(path, options);
  const body = await res.json().catch(() => ({}));
  if (res.status === 401) {
    body.error = "not signed in: open the address with ?token=… that the server printed when it started";
  }
  return { status: res.status, body };
}

// The annotator's name, asked once and kept in this browser: every save is logged with it
// (manifests/review_log.csv), and a stale save names who changed the file.
const NAME_KEY = "dance3d.annotator";

function setupAnnotator() {
  const field = $("#annotator");
  field.value = localStorage.getItem(NAME_KEY) || "";
  field.classList.toggle("ask", !field.value);
  field.onchange = () => {
    localStorage.setItem(NAME_KEY, field.value.trim());
    field.classList.toggle("ask", !field.value.trim());
  };
}

function annotator() {
  let name = localStorage.getItem(NAME_KEY) || "";
  if (!name) {
    name = (prompt("Your name (recorded with each save):") || "").trim();
    if (name) { localStorage.setItem(NAME_KEY, name); $("#annotator").value = name; $("#annotator").classList.remove("ask"); }
  }
  return name;
}

document.addEventListener("DOMContentLoaded", setupAnnotator);

function setState(text, ok) { const s = $("#state"); s.textContent = text; s.className = ok ? "ok" : "bad"; }

function snapTo(t, fps) {  // to the nearest frame time, three decimals as the CSV files hold
  return Math.round(Math.round(t * fps) / fps * 1000) / 1000;
}

// Space, arrows (a frame; Shift: a second). Returns true when the key was one of these.
function transportKey(e, video, fps, duration) {
  const step = e.shiftKey ? 1 : 1 / fps;
  switch (e.key) {
    case " ": e.preventDefault(); video.paused ? video.play() : video.pause(); return true;
    case "ArrowLeft": e.preventDefault(); video.currentTime = Math.max(0, video.currentTime - step); return true;
    case "ArrowRight": e.preventDefault(); video.currentTime = Math.min(duration, video.currentTime + step); return true;
    default: return false;
  }
}

// The editing keys of both pages (trim mode uses the same keys as track cleaning); `extra`
// adds a page's own (key -> action name). `select(i, jump)` moves the selected row.
const EDIT_KEYS = { "[": "setStart", "]": "setEnd", s: "split", a: "add", Delete: "remove" };

function bindEditing(state, actions, select, buttons, extra) {
  for (const [sel, name] of Object.entries(buttons)) $(sel).onclick = actions[name];
  const keys = { ...EDIT_KEYS, ...extra };
  document.addEventListener("keydown", (e) => {
    if (e.target.tagName === "INPUT" || e.target.tagName === "SELECT") return;
    if ((e.ctrlKey || e.metaKey) && e.key === "s") { e.preventDefault(); actions.save(); return; }
    if (transportKey(e, $("#video"), state.fps, state.duration)) return;
    if (e.key === "ArrowUp" || e.key === "ArrowDown") {
      e.preventDefault();
      select(state.selected + (e.key === "ArrowUp" ? -1 : 1), false);
    } else if (e.key === "Enter") {
      select(state.selected, true);
    } else if (keys[e.key]) {
      actions[keys[e.key]]();
    }
  });
  window.addEventListener("beforeunload", (e) => { if (state.dirty) { e.preventDefault(); e.returnValue = ""; } });
}

function idFromPath(prefix) {  // "/segment/<id>" or "/trim/<id>" -> id, else null
  const m = location.pathname.match(new RegExp(`^/${prefix}/([A-Za-z0-9_-]+)$`));
  return m ? m[1] : null;
}

function drawPlayhead() {
  const t = $("#video").currentTime || 0;
  const head = $("#playhead");
  if (head) head.style.left = `${(100 * t) / state.duration}%`;
  $("#now").textContent = t.toFixed(3);
  $("#frame").textContent = Math.round(t * state.fps);
}

function select(i, jump) {
  if (!state.rows.length) return;
  state.selected = Math.max(0, Math.min(state.rows.length - 1, i));
  if (jump) $("#video").currentTime = state.rows[state.selected].start;
  renderAll();
}
