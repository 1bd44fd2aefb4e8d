// A motion clip shown in an <img> with a Pause/Play toggle (issue 41 §3), shared by the
// participant's bracket page (label.js) and the evaluator's pair page (evaluate.js). The
// <img> carries `data-clip` (the animated image) and `data-still` (its still): playing shows
// the clip, pausing swaps it for the still (WCAG 2.2.2). Under prefers-reduced-motion a page
// starts on the still, with a Play control. The toggle is named after what it does.
"use strict";

window.ACVMotion = {
  // Whether the participant asked for reduced motion (pages then start on the stills).
  reduced() {
    return window.matchMedia("(prefers-reduced-motion: reduce)").matches;
  },
  // Show `img`'s clip (playing) or its still (paused); `what` names it for screen readers.
  show(img, toggle, playing, what) {
    img.src = playing ? img.dataset.clip : img.dataset.still;
    img.dataset.playing = String(playing);
    const hidden = Object.assign(document.createElement("span"),
      { className: "visually-hidden", textContent: what });
    toggle.replaceChildren(`${playing ? "Pause" : "Play"} `, hidden);
    toggle.dataset.playing = String(playing);
  },
};
