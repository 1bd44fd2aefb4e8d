// Labelling page: one match at a time through the REST API, with the invite cookie.
// Choose with a click or tap on a picture, the Left/Right buttons, or the arrow keys; the
// response time sent is measured from the moment the page settles (both pictures decoded and
// on screen, the fade-in over) to the choice, so it measures the participant, not the fade.
// `#match` carries `data-ready` (the controls are enabled) and `data-settled` (enabled, and
// nothing on the page is animating): tests wait for `data-settled`. Undo takes
// back the latest label while no later match depends on it. A label's answer carries the
// next match (the page updates its live bracket from that answer, so a decision costs one
// request), and the next match's pictures are fetched while the participant decides, so
// the next pair appears at once. Where the match carries clips (`clip_url`: a study with
// clips, both rendered), each side plays its clip with a Pause/Play toggle that swaps it for
// its still (static/js/clip_motion.js); under prefers-reduced-motion the stills show, each
// with Play. The label says what was shown: `stimulus` "clip" once a clip has played.
/* global ACV, ACVMotion */
"use strict";

const API = {
  me: "/api/participants/me",
  next: "/api/participants/me/next-match",
  bracket: "/api/participants/me/bracket",
  undo: "/api/participants/me/undo",
  label: (matchId) => `/api/matches/${matchId}/label`,
  gold: (itemId) => `/api/participants/me/gold/${itemId}/label`,
};

// What the page shows now: a bracket match, or a gold item shown before it (its own key,
// since it precedes the match whose id it carries).
const shownKey = (next) => (next.gold ? `gold-${next.gold.item_id}` : String(next.match_id));

// `shown`: the match's pictures are on screen and settled; `shownAt`: when its controls
// began to answer (the response clock's start).
// `rounds`: the live bracket, fetched on load and after an undo, and otherwise kept up to
// date here from each label's answer, so that a decision costs one request.
const state = {
  match: null, shown: false, shownAt: null, busy: false, canUndo: false, rounds: [],
  stimulus: "still",
};
const $ = (id) => document.getElementById(id);

class ApiError extends Error {
  constructor(result) {
    super(result.status === 401
      ? "Your invitation was not recognised: open the link you were sent again."
      : ACV.errorText(result));
    this.status = result.status;
  }
}

// The match's controls. A control that is disabled while the next match loads loses the
// focus (to the page), so it gets it back once the match answers (WCAG 2.4.3).
const CHOICES = ["pick-a", "pick-b", "btn-left", "btn-right", "tie"];
const CONTROLS = [...CHOICES, "undo"];

function setEnabled() {
  const ready = !state.busy && state.shown;
  if (ready && state.shownAt === null) state.shownAt = performance.now();
  const focused = document.activeElement;
  if (!ready && focused && CONTROLS.includes(focused.id)) state.refocus = focused.id;
  for (const id of CHOICES) $(id).disabled = !ready;
  $("undo").disabled = state.busy || !state.canUndo;
  if (ready && state.refocus) {
    const lost = !document.activeElement || document.activeElement === document.body;
    if (lost) $(state.refocus).focus();
    state.refocus = null;
  }
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
  if (state.match && shownKey(state.match) === shownKey(next) && state.shown) return;
  state.match = next;
  state.shown = false;
  state.shownAt = null;
  const box = $("match");
  box.classList.add("loading");
  box.dataset.matchId = shownKey(next);
  // An instructed check says what to do; every other pair asks the study's question.
  $("prompt-text").textContent = next.gold && next.gold.prompt ? next.gold.prompt : $("prompt-text").dataset.question;
  $("tie").hidden = !next.allow_ties;
  const onScreen = placed(next);
  const images = [[$("img-a"), onScreen.a], [$("img-b"), onScreen.b]];
  const instructed = Boolean(next.gold && next.gold.prompt);
  state.stimulus = "still";
  images.forEach(([img, side], k) => {
    showSide(img, $(k === 0 ? "motion-a" : "motion-b"), side, k === 0 ? "left" : "right");
    img.alt = `candidate ${side.candidate_id}`;
    img.parentElement.classList.remove("chosen");
  });
  // The marker is drawn on a picture: say in words which one has it, for screen readers.
  images.forEach(([img, side], k) => {
    const where = k === 0 ? "left" : "right";
    const marked = side.image_url.includes("marker=true") ? "with" : "without";
    img.parentElement.setAttribute("aria-label", instructed
      ? `The ${where} picture, ${marked} the marker` : `Prefer the ${where} picture`);
  });
  await Promise.all(images.map(([img]) => img.decode().catch(() => undefined)));
  if (state.match !== next) return;  // a newer match replaced this one meanwhile
  box.classList.remove("loading");
  await settled();
  if (state.match === next) state.shown = true;  // the clock starts when the controls answer
}

// A side's picture, or its clip (playing unless the participant asked for reduced motion)
// with its toggle shown.
function showSide(img, toggle, side, where) {
  img.dataset.still = side.image_url;
  toggle.hidden = !side.clip_url;
  if (!side.clip_url) {
    delete img.dataset.clip;
    img.src = side.image_url;
    return;
  }
  img.dataset.clip = side.clip_url;
  play(img, toggle, !ACVMotion.reduced(), where);
}

function play(img, toggle, playing, where) {
  ACVMotion.show(img, toggle, playing, `the ${where} candidate`);
  if (playing) state.stimulus = "clip";
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

// Fetch the next match, the undo state and the live bracket (on load and after an undo);
// go to the thank-you page at the end.
async function refresh() {
  const [next, me, bracket] = await Promise.all(
    [ACV.api("GET", API.next), ACV.api("GET", API.me), ACV.api("GET", API.bracket)]);
  if (next.status === 204) {
    finish();
    return;
  }
  for (const result of [next, me, bracket]) if (result.status !== 200) throw new ApiError(result);
  state.canUndo = me.data.can_undo;
  state.rounds = bracket.data.rounds;
  showStatus(next.data);
  placeCurrent(state.rounds, next.data);
  drawBracket(state.rounds, next.data.match_id);
  preload(upcomingImageUrls(state.rounds, next.data));
  await showMatch(next.data);
}

// A decided match in the live bracket: its winner, who moves up into the next round's cell
// (first in it from an even slot, second from an odd one), as the server's bracket has it.
function recordLabel(rounds, decided) {
  rounds.forEach((cells, r) => cells.forEach((cell) => {
    if (cell.match_id !== decided.match_id) return;
    cell.winner = decided.winner;
    const parent = r + 1 < rounds.length ? rounds[r + 1][cell.slot >> 1] : null;
    if (parent) parent[cell.slot % 2 === 0 ? "a" : "b"] = decided.winner;
  }));
}

// The match shown now gets its id in its cell (it exists from the moment it is served).
function placeCurrent(rounds, next) {
  if (next.gold) return;  // a gold item is not a bracket match
  const players = [next.a.candidate_id, next.b.candidate_id].sort().join();
  for (const cell of rounds[next.round - 1] || []) {
    if ([cell.a, cell.b].sort().join() === players) cell.match_id = next.match_id;
  }
}

// After a label: show the next match its answer carried (its pictures are usually
// preloaded), and update the live bracket from the answer. The latest label can be undone.
async function advance(next, decided) {
  state.canUndo = true;
  showStatus(next);
  if (decided) recordLabel(state.rounds, decided);
  placeCurrent(state.rounds, next);
  drawBracket(state.rounds, next.match_id);
  preload(upcomingImageUrls(state.rounds, next));
  await showMatch(next);
}

// Run one action (label or undo) at a time, then show the new state: the next match the
// action's answer carried (with the match it decided), or else what the server says now.
async function act(action) {
  state.busy = true;
  setEnabled();
  try {
    const outcome = await action();
    if (outcome === undefined) await refresh();
    else if (outcome.next === null) finish();
    else await advance(outcome.next, outcome.decided);
  } catch (err) {
    say(err.message, true);
  } finally {
    state.busy = false;
    setEnabled();
  }
}

// Send the answer to what is shown: a gold item's, a tie ("can't tell"), or a winner.
function answer(match, side, responseMs) {
  if (match.gold) {
    return ACV.api("POST", API.gold(match.gold.item_id),
      { winner: placed(match)[side].candidate_id, response_ms: responseMs });
  }
  const decision = side === "tie" ? { tie: true } : { winner: placed(match)[side].candidate_id };
  return ACV.api("POST", API.label(match.match_id),
    { ...decision, response_ms: responseMs, stimulus: state.stimulus });
}

function choose(side) {
  if (state.busy || state.shownAt === null) return;
  if (side === "tie" && !state.match.allow_ties) return;
  const match = state.match;
  const responseMs = Math.max(0, Math.round(performance.now() - state.shownAt));
  if (side !== "tie") $(side === "a" ? "pick-a" : "pick-b").classList.add("chosen");
  act(async () => {
    const result = await answer(match, side, responseMs);
    if (result.status === 410) {  // withdrew, or out of time: the page says which
      window.location.assign($("labelling").dataset.endedUrl);
      return undefined;
    }
    if (result.status === 409) {
      say("That pair was already decided (in another window?).");
      return undefined;
    }
    if (result.status !== 201 && result.status !== 200) throw new ApiError(result);
    say("");
    // `next` is null once the bracket is finished; a gold answer decides no match.
    return { next: result.data.next, decided: match.gold ? null : result.data };
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
  } else if (event.key === "t" || event.key === "T") {
    choose("tie");
  }
}

(function () {
  if (!$("labelling")) return;
  for (const el of document.querySelectorAll("#labelling [data-side]")) {
    el.addEventListener("click", () => choose(el.dataset.side));
  }
  for (const toggle of document.querySelectorAll("#labelling [data-motion]")) {
    const img = $(`img-${toggle.dataset.motion}`);
    const where = toggle.dataset.motion === "a" ? "left" : "right";
    toggle.addEventListener("click", () => play(img, toggle, img.dataset.playing !== "true", where));
  }
  $("undo").addEventListener("click", undo);
  $("tie").addEventListener("click", () => choose("tie"));
  document.addEventListener("keydown", onKey);
  act(async () => undefined);  // first load
})();
