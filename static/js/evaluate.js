// An evaluator's pair page (templates/evaluate_pair.html): the server sends stills; a side
// with a clip plays it, with a Pause/Play toggle (WCAG 2.2.2: pausing swaps the clip for its
// still). Under prefers-reduced-motion the stills stay, each with a Play control. The keys of
// the bracket page choose: ← the left agent, → the right one, T "Can't tell". The form posts
// what was shown (`stimulus`: "clip" once a clip has played) and the time to answer. The
// toggle itself is static/js/clip_motion.js's, shared with the bracket page.
/* global ACVMotion */
"use strict";

(function () {
  const form = document.getElementById("pair");
  if (!form) return;
  const reduced = ACVMotion.reduced();
  const KEYS = { ArrowLeft: "pick-left", ArrowRight: "pick-right", t: "tie", T: "tie" };
  let sent = false;

  // Show `side`'s clip (playing) or its still (paused), and name the toggle after what it does.
  function show(side, playing) {
    const img = document.getElementById(`img-${side}`);
    const toggle = document.getElementById(`motion-${side}`);
    ACVMotion.show(img, toggle, playing, `the ${side} agent`);
    if (playing) document.getElementById("stimulus").value = "clip";
  }

  for (const toggle of form.querySelectorAll("button.motion")) {
    const side = toggle.dataset.side;
    toggle.hidden = false;
    toggle.addEventListener("click", () => show(side, toggle.dataset.playing !== "true"));
    show(side, !reduced);
  }

  form.addEventListener("submit", (event) => {
    if (sent) {  // one answer per page: a second click or key press is not sent again
      event.preventDefault();
      return;
    }
    sent = true;
    document.getElementById("response-ms").value = String(Math.round(performance.now()));
  });
  // Back to this page from the browser's cache: it may be answered again (the server decides).
  window.addEventListener("pageshow", () => { sent = false; });

  document.addEventListener("keydown", (event) => {
    if (event.repeat || event.altKey || event.ctrlKey || event.metaKey) return;
    const id = KEYS[event.key];
    if (!id) return;
    event.preventDefault();
    form.requestSubmit(document.getElementById(id));
  });
  form.dataset.ready = "true";
})();
