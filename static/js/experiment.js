// The experiment page: while runs train, poll the experiment every few seconds and update
// each run's status and progress; when a verdict appears, or changes step or the runs it
// rests on, reload the page (the verdict is rendered on the server). Stops once every run
// has ended.
/* global ACV */
"use strict";

(function () {
  const root = document.getElementById("experiment");
  if (!root) return;
  const POLL_MS = 4000;
  const live = (status) => status === "queued" || status === "running";

  function update(runs) {
    for (const run of runs) {
      const row = root.querySelector(`tr[data-run-id="${run.id}"]`);
      if (!row) continue;
      const badge = row.querySelector("[data-status]");
      badge.textContent = run.status;
      badge.className = `badge run-${run.status}`;
      const progress = row.querySelector("[data-progress]");  // an imported policy has none
      if (progress) progress.textContent = `${run.progress.done} / ${run.progress.total}`;
    }
  }

  // The template's data-verdict-key: the step, every run id it rests on, in order, and
  // whether it is final (the runs' last checkpoint can be judged before they end).
  function verdictKey(found) {
    const ids = Object.values(found.runs).flat().sort((a, b) => a - b);
    return `${found.step}:${ids.join(",")}:${found.final ? "final" : "interim"}`;
  }

  async function poll() {
    const experiment = await ACV.api("GET", root.dataset.experimentUrl);
    if (experiment.status !== 200) return;
    update(experiment.data.runs);
    const verdictUrl = `${root.dataset.experimentUrl}/verdict?judge=${root.dataset.judge}`;
    const verdict = await ACV.api("GET", verdictUrl);
    if (verdict.status === 200 && verdictKey(verdict.data) !== root.dataset.verdictKey) {
      window.location.reload();
      return;
    }
    if (experiment.data.runs.some((run) => live(run.status))) setTimeout(poll, POLL_MS);
  }

  root.dataset.ready = "true";
  setTimeout(poll, POLL_MS);
})();
