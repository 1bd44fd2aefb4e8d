// A pair asked after the bracket (templates/_choice_form.html: the disagreement pairs and the
// consistency check) whose two clips are rendered: each side plays its clip with a Pause/Play
// toggle that swaps it for its still (static/js/clip_motion.js, as on the bracket page; WCAG
// 2.2.2). Under prefers-reduced-motion the stills stay, each with a Play control. The form
// posts what was shown: `stimulus` "clip" once a clip has played. Without JavaScript the
// stills show, with no toggle, and the form posts "still".
/* global ACVMotion */
"use strict";

(function () {
  const form = document.querySelector("form.check-pair[data-clips]");
  if (!form) return;
  const reduced = ACVMotion.reduced();

  // Show the clip of `toggle`'s side (playing) or its still (paused).
  function show(toggle, playing) {
    const img = toggle.parentElement.querySelector("img[data-clip]");
    ACVMotion.show(img, toggle, playing, `the ${toggle.dataset.side} candidate`);
    if (playing) form.elements.stimulus.value = "clip";
  }

  for (const toggle of form.querySelectorAll("button.motion")) {
    toggle.hidden = false;
    toggle.addEventListener("click", () => show(toggle, toggle.dataset.playing !== "true"));
    show(toggle, !reduced);
  }
  form.dataset.ready = "true";
})();
