// Labelling page: one match at a time through the REST API, with the invite cookie.
// Choose with a click or tap on a picture, the Left/Right buttons, or the arrow keys; the
// response time sent is measured from the moment the page settles (both pictures decoded and
// on screen, the fade-in over) to the choice, so it measures the participant, not the fade.
// `#match` carries `data-ready` (the controls are enabled) and `data-settled` (enabled, and
// nothing on the page is animating): tests wait for `data-settled`. Undo takes
// back the latest label while no later match depends on it. A label's answer carries the
// next match, and the next match's pictures are fetched while the participant decides, so
// the next pair appears at once.
/* global ACV */
"use strict";

const API = {
  me: "/api/participants/me",
  next: "/api/participants/me/next-match",
  bracket: "/api/participants/me/bracket",
  undo: "/api/participants/me/undo",
  label: (matchId) => `/api/matches/${matchId}/label`,
};

// `shown`: the match's pictures are on screen and settled; `shownAt`: when its controls
// began to answer (the response clock's start).
const state = { match: null, shown: false, shownAt: null, busy: false, canUndo: false };
const $ = (id) => document.getElementById(id);

class ApiError extends Error {
  constructor(result) {
    super(result.status === 401
      ? "Your invitation was not recognised: open your invite link again."
      : ACV.errorText(result));
    this.status = result.status;
  }
}

function setEnabled() {
  const ready = !state.busy && state.shown;
  if (ready && state.shownAt === null) state.shownAt = performance.now();
  for (const id of ["pick-a", "pick-b", "btn-left", "btn-right"]) $(id).disabled = !ready;
  $("undo").disabled = state.busy || !state.canUndo;
  $("match").setAttribute("aria-busy", String(!ready));
  $("match").dataset.ready = String(ready);
  $("match").dataset.settled = String(ready && document.getAnimations().length === 0);
}

// Resolves once no animation or transition runs on the page (the match's fade-in, the
// progress bar), however long they take: `transitionend` never fires when a transition is
// skipped (prefers-reduced-motion), but an empty `getAnimations()` always comes.
async function settled() {
  for (let animations = document.getAnimations(); animations.length > 0;
    animations = document.getAnimations()) {
    await Promise.all(animations.map((a) => a.finished.catch(() => undefined)));
  }
}

function say(text, isError) {
  $("message").textContent = text || "";
  $("message").classList.toggle("error", Boolean(isError));
}

function showStatus(next) {
  const { done, total } = next.progress;
  $("round-text").textContent = `Round ${next.round} of ${next.n_rounds}, ` +
    `match ${next.match_number} of ${next.matches_in_round}`;
  $("count-text").textContent = `${done} of ${total} decided`;
  $("progress-bar").style.width = `${total ? (100 * done) / total : 0}%`;
  $("progress").setAttribute("aria-valuenow", String(done));
}

// The match's candidates as placed on screen: the server randomises which one is on the
// left (`left`), so the page's "a" button is the left picture, not necessarily `a`.
function placed(next) {
  return next.left === next.b.candidate_id ? { a: next.b, b: next.a } : { a: next.a, b: next.b };
}

// Show the two pictures; the clock starts once both are decoded, on screen and settled.
async function showMatch(next) {
  if (state.match && state.match.match_id === next.match_id && state.shown) return;
  state.match = next;
  state.shown = false;
  state.shownAt = null;
  const box = $("match");
  box.classList.add("loading");
  box.dataset.matchId = String(next.match_id);
  const onScreen = placed(next);
  const images = [[$("img-a"), onScreen.a], [$("img-b"), onScreen.b]];
  for (const [img, side] of images) {
    img.src = side.image_url;
    img.alt = `candidate ${side.candidate_id}`;
    img.parentElement.classList.remove("chosen");
  }
  await Promise.all(images.map(([img]) => img.decode().catch(() => undefined)));
  if (state.match !== next) return;  // a newer match replaced this one meanwhile
  box.classList.remove("loading");
  await settled();
  if (state.match === next) state.shown = true;  // the clock starts when the controls answer
}

// Pictures fetched ahead, kept referenced so that the browser keeps them decoded.
const preloaded = new Map();

function preload(urls) {
  for (const url of urls) {
    if (preloaded.has(url)) continue;
    const img = new Image();
    img.src = url;
    preloaded.set(url, img);
    img.decode().catch(() => undefined);
  }
}

// The pictures of the match that follows `current` (the first undecided one after it with
// both players known). A later-round match that waits for `current` is between players
// already shown, so those never need fetching.
function upcomingImageUrls(rounds, current) {
  const path = (id) => current.a.image_url.replace(
    `/candidates/${current.a.candidate_id}/`, `/candidates/${id}/`);
  for (const cells of rounds) {
    for (const cell of cells) {
      if (cell.is_bye || cell.winner !== null || cell.match_id === current.match_id) continue;
      if (cell.a !== null && cell.b !== null) return [path(cell.a), path(cell.b)];
    }
  }
  return [];
}

function finish() {
  window.location.assign($("labelling").dataset.thanksUrl);
}

// Fetch the next match, the undo state and the live bracket; go to the thank-you page at
// the end.
async function refresh() {
  const [next, me, bracket] = await Promise.all(
    [ACV.api("GET", API.next), ACV.api("GET", API.me), ACV.api("GET", API.bracket)]);
  if (next.status === 204) {
    finish();
    return;
  }
  for (const result of [next, me, bracket]) if (result.status !== 200) throw new ApiError(result);
  state.canUndo = me.data.can_undo;
  showStatus(next.data);
  drawBracket(bracket.data.rounds, next.data.match_id);
  preload(upcomingImageUrls(bracket.data.rounds, next.data));
  await showMatch(next.data);
}

// After a label: show the next match its answer carried (its pictures are usually
// preloaded), and redraw the live bracket meanwhile. The latest label can always be undone.
async function advance(next) {
  state.canUndo = true;
  showStatus(next);
  const bracket = ACV.api("GET", API.bracket).then((result) => {
    if (result.status !== 200) throw new ApiError(result);
    drawBracket(result.data.rounds, next.match_id);
    preload(upcomingImageUrls(result.data.rounds, next));
  });
  await Promise.all([showMatch(next), bracket]);
}

// Run one action (label or undo) at a time, then show the new state: the next match the
// action returned, or else whatever the server says now.
async function act(action) {
  state.busy = true;
  setEnabled();
  try {
    const next = await action();
    if (next === null) finish();
    else if (next !== undefined) await advance(next);
    else await refresh();
  } catch (err) {
    say(err.message, true);
  } finally {
    state.busy = false;
    setEnabled();
  }
}

function choose(side) {
  if (state.busy || state.shownAt === null) return;
  const match = state.match;
  const responseMs = Math.max(0, Math.round(performance.now() - state.shownAt));
  $(side === "a" ? "pick-a" : "pick-b").classList.add("chosen");
  act(async () => {
    const result = await ACV.api("POST", API.label(match.match_id),
      { winner: placed(match)[side].candidate_id, response_ms: responseMs });
    if (result.status === 409) {
      say("That match was already decided (in another window?).");
      return undefined;
    }
    if (result.status !== 201 && result.status !== 200) throw new ApiError(result);
    say("");
    return result.data.next;  // null once the bracket is finished
  });
}

function undo() {
  if (state.busy || !state.canUndo) return;
  act(async () => {
    const result = await ACV.api("POST", API.undo);
    if (result.status !== 200) throw new ApiError(result);
    state.match = null;  // show the reopened match even if it has the same id
    say(`Undone: round ${result.data.round} is open again.`);
  });
}

function playerChip(id, cell, thumbTemplate) {
  const chip = document.createElement("span");
  chip.className = "p";
  if (id === null) {
    chip.textContent = "?";
    return chip;
  }
  const img = document.createElement("img");
  img.src = ACV.thumbUrl(thumbTemplate, id);
  img.alt = "";
  chip.append(img, `#${id}`);
  if (cell.winner !== null && !cell.is_bye) {
    const won = cell.winner === id;
    chip.classList.add(won ? "w" : "l");
    // Said in words and by a mark, not by colour or faintness alone.
    const mark = Object.assign(document.createElement("span"),
      { className: "mark", textContent: won ? "✓" : "✗" });
    mark.setAttribute("aria-hidden", "true");
    const word = Object.assign(document.createElement("span"),
      { className: "visually-hidden", textContent: won ? " won" : " lost" });
    chip.append(mark, word);
  }
  return chip;
}

// The live bracket: one column per round, one box per match, winners marked.
function drawBracket(rounds, currentId) {
  const template = $("labelling").dataset.thumbTemplate;
  const columns = rounds.map((cells, r) => {
    const column = document.createElement("div");
    column.className = "round";
    const title = document.createElement("div");
    title.className = "round-title";
    title.textContent = r === rounds.length - 1 ? "Final" : `Round ${r + 1}`;
    const boxes = document.createElement("div");
    boxes.className = "cells";
    column.append(title, boxes);
    for (const cell of cells) {
      const box = document.createElement("div");
      box.className = "m" + (cell.is_bye ? " bye" : "") +
        (cell.winner !== null && !cell.is_bye ? " decided" : "") +
        (cell.match_id !== null && cell.match_id === currentId ? " current" : "");
      box.append(playerChip(cell.a, cell, template));
      box.append(cell.is_bye ? Object.assign(document.createElement("span"),
        { className: "p bye-note", textContent: "bye" }) : playerChip(cell.b, cell, template));
      boxes.append(box);
    }
    return column;
  });
  $("mini-bracket").replaceChildren(...columns);
}

function onKey(event) {
  if (event.repeat || event.altKey || event.ctrlKey || event.metaKey) return;
  if (event.key === "ArrowLeft" || event.key === "ArrowRight") {
    event.preventDefault();
    choose(event.key === "ArrowLeft" ? "a" : "b");
  } else if (event.key === "u" || event.key === "U") {
    undo();
  }
}

(function () {
  if (!$("labelling")) return;
  for (const el of document.querySelectorAll("#labelling [data-side]")) {
    el.addEventListener("click", () => choose(el.dataset.side));
  }
  $("undo").addEventListener("click", undo);
  document.addEventListener("keydown", onKey);
  act(async () => undefined);  // first load
})();
