// dance3d review page: plays the QC video, shows one timeline lane per track id, edits the
// manifest rows, and saves them through the server, which runs the manifest checker.
"use strict";

const state = { seg: null, rows: [], selected: 0, version: "", fps: 24, duration: 1, dirty: false };

async function showList() {
  $("#list-view").hidden = false;
  const { body } = await api("/api/segments");
  const tbody = $("#segments tbody");
  tbody.innerHTML = "";
  for (const s of body) {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td><a href="/segment/${s.id}">${s.id}</a></td><td class="status-${s.status}">${s.status}</td>` +
      `<td>${s.errors}</td>`;
    tbody.appendChild(tr);
  }
}

async function showSegment(id) {
  $("#segment-view").hidden = false;
  $("#where").textContent = "· " + id;
  const { body } = await api(`/api/segments/${id}`);
  state.seg = body;
  state.rows = body.rows.map((r) => ({ ...r }));
  state.version = body.version;
  state.fps = body.fps;
  state.duration = body.duration;
  state.selected = 0;
  const video = $("#video");
  video.src = `/qc/${id}.mp4`;
  video.addEventListener("timeupdate", drawPlayhead);
  video.addEventListener("seeked", drawPlayhead);
  renderAll();
  showProblems(body.problems);
  setState(body.has_manifest ? `loaded (${body.status})` : "proposal (not saved yet)", true);
}

function now() { return Math.round($("#video").currentTime * 1000) / 1000; }

const snap = (t) => snapTo(t, state.fps);  // to the nearest frame time, so spans match the QC timecode

function renderAll() { renderRows(); renderTimeline(); }

function renderRows() {
  const tbody = $("#rows tbody");
  tbody.innerHTML = "";
  state.rows.forEach((r, i) => {
    const tr = document.createElement("tr");
    tr.className = i === state.selected ? "selected" : "";
    tr.dataset.index = i;
    tr.innerHTML =
      `<td><input class="num" data-field="track_id" value="${r.track_id}"></td>` +
      `<td><input class="num" data-field="start" value="${r.start.toFixed(3)}"></td>` +
      `<td><input class="num" data-field="end" value="${r.end.toFixed(3)}"></td>` +
      `<td><select data-field="keep"><option value="yes">yes</option><option value="no">no</option></select></td>` +
      `<td><input class="note" data-field="note"></td><td class="reason"></td>`;
    tr.querySelector("select").value = r.keep ? "yes" : "no";
    tr.querySelector(".note").value = r.note || "";
    tr.querySelector(".reason").textContent = (r.info && r.info.reason) || "";
    tr.addEventListener("click", () => select(i, false));
    tr.querySelectorAll("input, select").forEach((el) => el.addEventListener("change", () => edit(i, el)));
    tbody.appendChild(tr);
  });
}

function edit(i, el) {
  const r = state.rows[i];
  const f = el.dataset.field;
  if (f === "keep") r.keep = el.value === "yes";
  else if (f === "note") r.note = el.value;
  else r[f] = f === "track_id" ? parseInt(el.value, 10) : parseFloat(el.value);
  changed();
}

function renderTimeline() {
  const box = $("#timeline");
  box.innerHTML = "";
  const ids = [...new Set(state.seg.tracks.map((t) => t.id).concat(state.rows.map((r) => r.track_id)))].sort((a, b) => a - b);
  for (const id of ids) {
    const lane = document.createElement("div");
    lane.className = "lane";
    lane.innerHTML = `<span class="lane-label">${id}</span>`;
    state.rows.forEach((r, i) => {
      if (r.track_id !== id) return;
      const span = document.createElement("div");
      span.className = `span ${r.keep ? "keep" : "reject"}${i === state.selected ? " selected" : ""}`;
      span.style.left = `${(100 * r.start) / state.duration}%`;
      span.style.width = `${Math.max(0.3, (100 * (r.end - r.start)) / state.duration)}%`;
      span.title = `track ${id}: ${r.start.toFixed(3)}-${r.end.toFixed(3)} s, ${r.keep ? "keep" : "reject"}` +
        ((r.info && r.info.reason) ? ` (${r.info.reason})` : "");
      span.addEventListener("click", (e) => { e.stopPropagation(); select(i, true); });
      lane.appendChild(span);
    });
    box.appendChild(lane);
  }
  const head = document.createElement("div");
  head.id = "playhead";
  box.appendChild(head);
  box.onclick = (e) => {
    const rect = box.getBoundingClientRect();
    $("#video").currentTime = ((e.clientX - rect.left) / rect.width) * state.duration;
  };
  drawPlayhead();
}

function changed() { state.dirty = true; setState("unsaved changes", true); renderAll(); }

function current() { return state.rows[state.selected]; }

const actions = {
  setStart() { const r = current(); if (r) { r.start = snap(now()); changed(); } },
  setEnd() { const r = current(); if (r) { r.end = snap(now()); changed(); } },
  toggle() { const r = current(); if (r) { r.keep = !r.keep; changed(); } },
  split() {
    const r = current();
    const t = snap(now());
    if (!r || t <= r.start || t >= r.end) { setState("move the playhead inside the selected span to split it", false); return; }
    const second = { ...r, info: { ...r.info }, start: snap(t + 1 / state.fps) };
    r.end = t;
    state.rows.splice(state.selected + 1, 0, second);
    changed();
  },
  add() {
    const r = current();
    const id = r ? r.track_id : (state.seg.tracks[0] || { id: 0 }).id;
    const t = snap(now());
    state.rows.push({ track_id: id, start: t, end: snap(Math.min(state.duration, t + 1)), keep: true, note: "", info: {} });
    state.selected = state.rows.length - 1;
    changed();
  },
  remove() { if (current()) { state.rows.splice(state.selected, 1); state.selected = Math.max(0, state.selected - 1); changed(); } },
  async save() {
    setState("saving…", true);
    const { status, body } = await api(`/api/segments/${state.seg.id}`, {
      method: "PUT", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ version: state.version, rows: state.rows, annotator: annotator() }),
    });
    if (status === 200) {
      state.version = body.version;
      state.dirty = false;
      showProblems(body.problems || []);
      setState(body.unchanged ? "saved (no changes)" : "saved", true);
    } else if (status === 409) {
      setState(body.error, false);
      if (confirm(body.error + "\n\nReload the page now?")) location.reload();
    } else {
      showProblems(body.problems || []);
      setState(body.error || `save failed (${status})`, false);
    }
  },
};

function showProblems(problems) {
  const ul = $("#problems");
  ul.innerHTML = "";
  for (const p of problems) {
    const li = document.createElement("li");
    li.className = p.warning ? "warning" : "error";
    li.textContent = p.text;
    ul.appendChild(li);
  }
}

bindEditing(state, actions, select,
  { "#set-start": "setStart", "#set-end": "setEnd", "#split": "split", "#toggle": "toggle", "#add": "add",
    "#remove": "remove", "#save": "save" },
  { k: "toggle" });
const id = idFromPath("segment");
if (id) showSegment(id); else showList();
