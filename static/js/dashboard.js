// Study page, "Live" section (templates/_study_dashboard.html): keeps the server-rendered
// dashboard current without a reload. Polls GET /api/studies/{id}/dashboard every
// `data-poll-ms` with the last ETag as If-None-Match, so that an unchanged dashboard is a
// 304 with no body (one cheap query on the server). Polling stops while the tab is hidden
// or the researcher pauses it, and resumes at once when either ends.
"use strict";

(function () {
  const root = document.getElementById("dashboard");
  if (!root) return;
  const every = Number(root.dataset.pollMs) || 2500;
  const toggle = document.getElementById("live-toggle");
  const updated = document.getElementById("live-updated");
  let etag = root.dataset.version || "";
  let paused = false;
  let timer = null;
  let inFlight = false;
  root.dataset.updates = "0";  // bodies applied (200s); tests wait on these counters
  root.dataset.unchanged = "0";  // 304s

  function clock(date) {
    return date.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit", hour12: false });
  }

  function stamp(text, date) {
    const time = document.createElement("time");
    if (date) {
      time.dateTime = date.toISOString();
      time.textContent = clock(date);
    }
    updated.replaceChildren(text, time);
  }

  function setText(el, text) {
    if (el.textContent !== text) el.textContent = text;  // a live region re-announces any write
  }

  function cell(tag, text, className) {
    const el = document.createElement(tag);
    if (text !== undefined) el.textContent = text;
    if (className) el.className = className;
    return el;
  }

  function flagsCell(p) {
    const td = cell("td");
    const flags = p.excluded ? [...p.flags, "excluded"] : p.flags;
    flags.forEach((f) => td.append(cell("span", f.replace(/_/g, " "), "flag"), " "));
    return td;
  }

  function progressCell(p) {
    const td = cell("td", undefined, "progress-cell");
    const bar = document.createElement("progress");
    bar.max = p.total;
    bar.value = p.done;
    bar.setAttribute("aria-label", `#${p.participant_id}: ${p.done} of ${p.total} decisions`);
    td.append(bar, " ", cell("span", `${p.done}/${p.total}`, "small"));
    return td;
  }

  function row(p) {
    const tr = document.createElement("tr");
    tr.dataset.participantId = String(p.participant_id);
    const who = [`#${p.participant_id}`, p.name, p.external_id].filter(Boolean).join(" · ");
    const head = cell("th", who);
    head.scope = "row";
    const median = p.median_response_ms === null ? "" : `${Math.round(p.median_response_ms)} ms`;
    const gold = p.gold_asked ? `${p.gold_right} of ${p.gold_asked}` : "";
    tr.append(head, cell("td", p.status.replace(/_/g, " ")), progressCell(p),
      cell("td", median), cell("td", gold), flagsCell(p));
    return tr;
  }

  function render(data) {
    for (const [name, value] of Object.entries(data.counts)) {
      const el = root.querySelector(`[data-count="${name}"]`);
      if (el) setText(el, String(value));
    }
    setText(root.querySelector('[data-field="labels_last_minute"]'), String(data.labels_last_minute));
    setText(root.querySelector('[data-field="labels_per_minute"]'), data.labels_per_minute.toFixed(1));
    setText(root.querySelector('[data-field="labels"]'), String(data.labels));
    root.querySelector("#live-table tbody").replaceChildren(...data.participants.map(row));
    document.getElementById("live-empty").hidden = data.participants.length > 0;
  }

  function bump(name) {
    root.dataset[name] = String(Number(root.dataset[name]) + 1);
  }

  async function poll() {
    if (inFlight) return;
    inFlight = true;
    try {
      const response = await fetch(root.dataset.url, {
        headers: { "Accept": "application/json", "X-Requested-With": "acv", "If-None-Match": etag },
        credentials: "same-origin",
        cache: "no-store",
      });
      if (response.status === 200) {
        const data = await response.json();
        render(data);
        etag = response.headers.get("ETag") || data.version;
        root.dataset.version = etag;
        bump("updates");
      } else if (response.status === 304) {
        bump("unchanged");
      } else if (response.status === 401) {
        stamp("Signed out: log in again to see updates. Last update ", null);
        paused = true;
        toggle.hidden = true;
        return;
      } else {
        throw new Error(`the server answered ${response.status}`);
      }
      stamp("Updated ", new Date());
    } catch (err) {
      stamp(`Could not update (${err.message}); retrying. Last try `, new Date());
    } finally {
      inFlight = false;
      schedule();
    }
  }

  function schedule() {
    clearTimeout(timer);
    timer = null;
    if (!paused && document.visibilityState === "visible") timer = setTimeout(poll, every);
  }

  function setPaused(value) {
    paused = value;
    toggle.textContent = paused ? "Resume updates" : "Pause updates";
    if (paused) schedule();
    else poll();
  }

  const first = updated.querySelector("time");
  if (first && first.dateTime) stamp("Updated ", new Date(first.dateTime));
  toggle.hidden = false;
  toggle.addEventListener("click", () => setPaused(!paused));
  document.addEventListener("visibilitychange", () => {
    if (document.visibilityState === "visible" && !paused) poll();
    else schedule();
  });
  schedule();
})();
