// An evaluation's page (templates/evaluation.html): while its stills or clips render, poll the
// evaluation every few seconds and reload the page once its status, clips or error change
// (the page is rendered on the server).
/* global ACV */
"use strict";

(function () {
  const root = document.getElementById("evaluation");
  if (!root || root.dataset.watch !== "true") return;
  const POLL_MS = 2000;

  async function poll() {
    const found = await ACV.api("GET", root.dataset.evaluationUrl);
    if (found.status === 200) {
      const e = found.data;
      const state = `${e.status}:${e.clips_ready ? "True" : "False"}:${e.error !== null ? "True" : "False"}`;
      if (state !== root.dataset.state) {
        window.location.reload();
        return;
      }
    }
    window.setTimeout(poll, POLL_MS);
  }
  window.setTimeout(poll, POLL_MS);
})();
