// dance3d review, trim mode: plays a downloaded video, shows its shots, cues and proposed dance
// segments on a timeline, and edits its rows of annotations/segments.csv through the server,
// which checks them as the trim stage does.
"use strict";

const state = { video: null, rows: [], selected: 0, version: "", fps: 25, duration: 1, dirty: false, problems: [] };

async function showList() {
  $("#list-view").hidden = false;
  const { body } = await api("/api/videos");
  const tbody = $("#videos tbody");
  tbody.innerHTML = "";
  for (const v of body) {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td><a href="/trim/${v.id}">${v.id}</a></td><td class="status-${v.status}">${v.status}</td>` +
      `<td>${v.rows}</td><td>${v.proposals}</td><td>${v.duration.toFixed(1)}</td><td></td>`;
    tr.lastChild.textContent = v.title || "";
    tbody.appendChild(tr);
  }
}

async function showVideo(id) {
  $("#video-view").hidden = false;
  $("#where").textContent = "· " + id;
  const { body } = await api(`/api/videos/${id}`);
  state.video = body;
  state.rows = body.rows.map((r) => ({ ...r }));
  state.version = body.version;
  state.fps = body.fps;
  state.duration = body.duration;
  const video = $("#video");
  video.src = `/raw/${id}`;
  video.addEventListener("timeupdate", drawPlayhead);
  video.addEventListener("seeked", drawPlayhead);
  renderAll();
  setState(body.has_rows ? "loaded" : (body.proposals.length ? "proposals (not saved yet)" : "no segments yet"), true);
}

const now = () => Math.round($("#video").currentTime * 1000) / 1000;
const snap = (t) => snapTo(t, state.fps);
const current = () => state.rows[state.selected];
const pct = (t) => `${(100 * t) / state.duration}%`;

function renderAll() { renderRows(); renderTimeline(); }

function problemOf(i) { return state.problems.find((p) => p.row === i); }

function renderRows() {
  const tbody = $("#rows tbody");
  tbody.innerHTML = "";
  state.rows.forEach((r, i) => {
    const tr = document.createElement("tr");
    const problem = problemOf(i);
    tr.className = (i === state.selected ? "selected" : "") + (problem ? " has-error" : "");
    tr.dataset.index = i;
    const num = (v) => (typeof v === "number" ? v.toFixed(3) : String(v));
    tr.innerHTML =
      `<td><input class="num" data-field="start" value="${num(r.start)}"></td>` +
      `<td><input class="num" data-field="end" value="${num(r.end)}"></td>` +
      `<td><input class="label" data-field="label"></td><td><input class="note" data-field="note"></td>` +
      `<td class="reason"></td>`;
    tr.querySelector(".label").value = r.label || "";
    tr.querySelector(".note").value = r.note || "";
    tr.querySelector(".reason").textContent = problem ? problem.message : (r.reason || "");
    tr.addEventListener("click", () => select(i, false));
    tr.querySelectorAll("input").forEach((el) => el.addEventListener("change", () => edit(i, el)));
    tbody.appendChild(tr);
  });
}

function edit(i, el) {
  const f = el.dataset.field;
  state.rows[i][f] = (f === "start" || f === "end") ? parseFloat(el.value) : el.value;
  changed();
}

function lane(name) {
  const div = document.createElement("div");
  div.className = "lane";
  div.innerHTML = `<span class="lane-label">${name}</span>`;
  return div;
}

function block(cls, start, end, title, onclick) {
  const span = document.createElement("div");
  span.className = `span ${cls}`;
  span.style.left = pct(start);
  span.style.width = `${Math.max(0.3, (100 * (end - start)) / state.duration)}%`;
  span.title = title;
  if (onclick) span.addEventListener("click", (e) => { e.stopPropagation(); onclick(); });
  return span;
}

function renderTimeline() {
  const box = $("#timeline");
  box.innerHTML = "";
  const cues = lane("cues");
  state.video.seconds.forEach((s, k) => {
    const cls = s.dance ? "cue-dance" : s.music ? "cue-music" : s.moving ? "cue-moving" : "cue-none";
    cues.appendChild(block(`cue ${cls}`, k, Math.min(k + 1, state.duration),
      `${k}-${k + 1} s: ${s.music ? "music" : "no music"}, ${s.moving ? "people moving" : s.people ? "people static" : "nobody"}`));
  });
  const shots = lane("shots");
  state.video.shots.forEach((s, i) => shots.appendChild(block(`shot shot-${i % 2} verdict-${s.verdict.replace(" ", "-")}`,
    s.start, s.end, `shot ${s.start.toFixed(2)}-${s.end.toFixed(2)} s: ${s.verdict} (${s.reason})`)));
  const proposed = lane("proposed");
  state.video.proposals.forEach((p) => proposed.appendChild(block("proposal", p.start, p.end,
    `proposed ${p.start.toFixed(2)}-${p.end.toFixed(2)} s: ${p.reason}`, () => { $("#video").currentTime = p.start; })));
  const mine = lane("segments");
  state.rows.forEach((r, i) => {
    if (typeof r.start !== "number" || typeof r.end !== "number") return;
    mine.appendChild(block(`keep${i === state.selected ? " selected" : ""}${problemOf(i) ? " error" : ""}`, r.start, r.end,
      `segment ${r.start.toFixed(3)}-${r.end.toFixed(3)} s ${r.label || ""}`, () => select(i, true)));
  });
  for (const l of [cues, shots, proposed, mine]) box.appendChild(l);
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

function sortRows() {  // rows in start order, the selection kept on the same row
  const chosen = current();
  state.rows.sort((a, b) => a.start - b.start);
  state.selected = Math.max(0, state.rows.indexOf(chosen));
}

const actions = {
  setStart() { const r = current(); if (r) { r.start = snap(now()); sortRows(); changed(); } },
  setEnd() { const r = current(); if (r) { r.end = snap(now()); changed(); } },
  split() {
    const r = current();
    const t = snap(now());
    if (!r || t <= r.start || t >= r.end) { setState("move the playhead inside the selected segment to split it", false); return; }
    const second = { ...r, start: t };  // end is exclusive: the halves meet at the playhead
    r.end = t;
    state.rows.splice(state.selected + 1, 0, second);
    changed();
  },
  add() {
    const t = snap(now());
    const row = { start: t, end: snap(Math.min(state.duration, t + 1)), label: "dance", note: "" };
    state.rows.push(row);
    state.selected = state.rows.length - 1;
    sortRows();
    changed();
  },
  remove() {
    if (!current()) return;
    state.rows.splice(state.selected, 1);
    state.selected = Math.max(0, state.selected - 1);
    changed();
  },
  accept() {
    const t = now();
    const p = state.video.proposals.find((q) => q.start <= t && t < q.end);
    if (!p) { setState("no proposal under the playhead", false); return; }
    if (state.rows.some((r) => r.start === p.start && r.end === p.end)) { setState("already a segment", false); return; }
    state.rows.push({ ...p });
    state.selected = state.rows.length - 1;
    sortRows();
    changed();
  },
  acceptAll() { state.rows = state.video.proposals.map((p) => ({ ...p })); state.selected = 0; changed(); },
  async save() {
    setState("saving…", true);
    const rows = state.rows.map((r) => ({ start: r.start, end: r.end, label: r.label || "", note: r.note || "" }));
    const { status, body } = await api(`/api/videos/${state.video.id}`, {
      method: "PUT", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ version: state.version, rows, annotator: annotator() }),
    });
    state.problems = body.problems || [];
    if (status === 200) {
      state.version = body.version;
      state.dirty = false;
      setState(body.unchanged ? "saved (no changes)" : "saved", true);
    } else if (status === 409) {
      setState(body.error, false);
      if (confirm(body.error + "\n\nReload the page now?")) location.reload();
    } else {
      setState(body.error || `save failed (${status})`, false);
    }
    showProblems();
    renderAll();
  },
};

function showProblems() {
  const ul = $("#problems");
  ul.innerHTML = "";
  for (const p of state.problems) {
    const li = document.createElement("li");
    li.className = p.blocking ? "error" : "warning";
    li.textContent = p.row !== null ? `segment ${p.row + 1}: ${p.text}` : `${p.text} (another video's row: not blocking)`;
    ul.appendChild(li);
  }
}

bindEditing(state, actions, select,
  { "#set-start": "setStart", "#set-end": "setEnd", "#split": "split", "#add": "add", "#remove": "remove",
    "#accept": "accept", "#accept-all": "acceptAll", "#save": "save" },
  { p: "accept" });
const videoId = idFromPath("trim");
if (videoId) showVideo(videoId); else showList();
