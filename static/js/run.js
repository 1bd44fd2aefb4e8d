// Run page: poll the run (GET /api/runs/{id}) and its new metrics rows while it is queued or
// running; update the progress bar, the metrics table, the learning curve, z over training
// and the checkpoints list. The page reloads when the run ends (to show resume/compare).
/* global ACV, acvPlots */
"use strict";

(function () {
  const POLL_MS = 1500;
  const root = document.getElementById("run");
  if (!root) return;
  const rows = [];
  let status = root.dataset.status;

  function number(v) {
    if (v === null || v === undefined) return "–";
    return Math.abs(v) >= 1000 || Number.isInteger(v) ? String(Math.round(v)) :
      String(Number(v.toPrecision(4)));
  }

  function showRun(run) {
    const bar = document.getElementById("run-progress");
    bar.max = run.progress.total;
    bar.value = run.progress.done;
    const pct = Math.floor(100 * run.progress.done / Math.max(1, run.progress.total));
    document.getElementById("progress-text").textContent =
      `${run.progress.done} / ${run.progress.total} steps (${pct}%)`;
    const badge = document.getElementById("run-status");
    badge.textContent = run.status;
    badge.className = `badge run-${run.status}`;
    for (const cell of root.querySelectorAll("#run-metrics td[data-key]")) {
      cell.textContent = number((run.metrics || {})[cell.dataset.key]);
    }
    const error = document.getElementById("run-error");
    error.hidden = !run.error;
    error.querySelector("pre").textContent = run.error || "";
  }

  function drawCharts() {
    const ret = rows.filter((r) => r.return_100 !== null && r.return_100 !== undefined);
    if (ret.length > 0) {
      acvPlots.lines(document.getElementById("chart-return"),
        [{ label: "return", points: ret.map((r) => [r.timesteps, r.return_100]) }],
        { xlabel: "timesteps", ylabel: "return" });
    }
    const z = rows.filter((r) => Number.isFinite(r.z_mean));
    if (z.length > 0) {
      acvPlots.lines(document.getElementById("chart-z"),
        [{ label: "z", points: z.map((r) => [r.timesteps, r.z_mean]),
           band: z.map((r) => [r.timesteps, r.z_mean - r.z_std, r.z_mean + r.z_std]) }],
        { xlabel: "timesteps", ylabel: "z" });
    }
  }

  async function fetchRows() {
    const after = rows.length ? rows[rows.length - 1].timesteps : -1;
    const result = await ACV.api("GET", `${root.dataset.metricsUrl}?after=${after}`);
    if (result.status === 200 && result.data.length > 0) {
      rows.push(...result.data);
      drawCharts();
    }
  }

  async function fetchCheckpoints() {
    const result = await ACV.api("GET", root.dataset.checkpointsUrl);
    if (result.status !== 200) return;
    const list = document.getElementById("run-checkpoints");
    const known = new Set([...list.querySelectorAll("li[data-step]")].map((li) => li.dataset.step));
    for (const { checkpoint } of result.data) {
      if (known.has(String(checkpoint))) continue;
      list.querySelector("li.empty")?.remove();
      const li = document.createElement("li");
      li.dataset.step = checkpoint;
      li.textContent = `step ${checkpoint}`;
      if (root.dataset.compareUrl) {
        const a = document.createElement("a");
        a.href = `${root.dataset.compareUrl}?checkpoint=${checkpoint}`;
        a.textContent = "compare";
        li.append(" · ", a);
        document.getElementById("compare-link")?.removeAttribute("hidden");
      }
      list.appendChild(li);
    }
  }

  async function poll() {
    try {
      const result = await ACV.api("GET", root.dataset.runUrl);
      if (result.status === 200) {
        showRun(result.data);
        await fetchRows();
        await fetchCheckpoints();
        if (result.data.status !== status) {
          status = result.data.status;
          if (status !== "queued" && status !== "running") {
            window.location.reload();
            return;
          }
        }
      }
    } catch (err) {
      // The server may be restarting: keep polling.
    }
    if (status === "queued" || status === "running") setTimeout(poll, POLL_MS);
  }

  fetchRows().catch(() => {});
  if (status === "queued" || status === "running") setTimeout(poll, POLL_MS);
})();
