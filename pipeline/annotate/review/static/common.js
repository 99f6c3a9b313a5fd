// Shared by both review pages (tracks: app.js, trim: trim.js): DOM lookup, the JSON API, the
// state line, and the player's transport keys.
"use strict";

const $ = (sel) => document.querySelector(sel);

async function api(path, options) {
  const res = await fetch(path, options);
  const body = await res.json().catch(() => ({}));
  return { status: res.status, body };
}

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
