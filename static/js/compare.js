// Comparison pages.
// One run (#compare): the Human and the Agent Preference Tree side by side (same drawing, same
// options), the overturned matches highlighted in both and listed as image pairs, the metrics
// with a one-line verdict, a checkpoint slider, and the conformance curve across training.
// Several runs on the same advice (#compare-runs): their agreement curves on one chart.
/* global ACV, ACVTree, acvPlots */
"use strict";

(function () {
  const THUMB = 64;

  const POLL_MS = 2000;
  const sleep = (ms) => new Promise((done) => setTimeout(done, ms));

  function figure(url, fullUrl, caption, cls, open) {
    const fig = document.createElement("figure");
    fig.className = cls;
    const img = document.createElement("img");
    img.src = url;
    img.alt = caption;
    img.width = img.height = 128;
    img.addEventListener("click", () => open(fullUrl, caption));
    const cap = document.createElement("figcaption");
    cap.textContent = caption;
    fig.append(img, cap);
    return fig;
  }

  function drawRejected(box, m, who, urls, open) {
    if (m.rejected.length === 0) {
      box.innerHTML = "";
      const p = document.createElement("p");
      p.textContent = "None: the agent kept every choice at this checkpoint.";
      box.appendChild(p);
      return;
    }
    const items = m.rejected.map((r) => {
      const other = r.human_winner === r.a ? r.b : r.a;
      const agentPick = r.agent_winner === null ? other : r.agent_winner;
      const item = document.createElement("div");
      item.className = "pair";
      item.dataset.round = r.round;
      const imgs = document.createElement("div");
      imgs.className = "imgs";
      imgs.append(
        figure(urls.thumb(r.human_winner), urls.full(r.human_winner), `#${r.human_winner}`, "human", open),
        figure(urls.thumb(agentPick), urls.full(agentPick), `#${agentPick}`, "agent", open));
      const text = document.createElement("p");
      text.textContent = `Round ${r.round}: ${who} preferred #${r.human_winner}, ` +
        (r.agent_winner === null ? `the agent could not decide against #${other}.` :
          `the agent preferred #${r.agent_winner}.`);
      if (r.contested) {
        item.classList.add("contested");
        const tag = document.createElement("strong");
        tag.textContent = "Contested: the advice went against the environment's reward. ";
        text.prepend(tag);
      }
      item.append(imgs, text);
      return item;
    });
    box.replaceChildren(...items);
  }

  function showMetrics(root, m) {
    const set = (key, text) => { root.querySelector(`[data-metric="${key}"]`).textContent = text; };
    set("match_agreement", `${m.n_agree} / ${m.n_matches}`);
    set("ci", `95% CI ${m.match_agreement_ci[0].toFixed(2)}–${m.match_agreement_ci[1].toFixed(2)}`);
    set("kendall_tau_b", m.kendall_tau_b === null ? "n/a" : m.kendall_tau_b.toFixed(3));
    set("tree_edit_distance", m.tree_edit_distance.toFixed(3));
    set("same_champion", m.same_champion ? "yes" : "no");
  }

  // A checkpoint's artefact may still be computing (202): show it, and ask again.
  async function getJson(url, onPending) {
    for (;;) {
      const result = await ACV.api("GET", url);
      if (result.status === 200) return result.data;
      if (result.status !== 202 || !onPending) throw new Error(ACV.errorText(result));
      onPending();
      await sleep(POLL_MS);
    }
  }

  function cell(row, text) {
    const td = document.createElement("td");
    if (text instanceof Node) td.appendChild(text); else td.textContent = text;
    row.appendChild(td);
  }

  function showJudges(body, report) {
    body.replaceChildren(...report.judges.map((j) => {
      const row = document.createElement("tr");
      row.dataset.judge = j.judge;
      if (j.judge === report.judge) row.classList.add("selected");
      cell(row, j.judge);
      cell(row, `${j.n_agree} / ${j.n_matches}`);
      cell(row, j.contested.n === 0 ? "none contested" : `${j.contested.kept} / ${j.contested.n}`);
      return row;
    }));
  }

  // Pooled advice: one row per participant's tree, then the pooled verdict's.
  function showAdvisors(body, report) {
    if (!body || !report.advisors) return;
    const kept = (m) => m.contested.n === 0 ? "none contested" :
      `${m.contested.kept} / ${m.contested.n}`;
    const row = (label, m, pid) => {
      const tr = document.createElement("tr");
      if (pid !== null) tr.dataset.participant = pid; else tr.dataset.pooled = "1";
      const th = document.createElement("th");
      th.scope = "row";
      th.textContent = label;
      tr.appendChild(th);
      cell(tr, kept(m));
      cell(tr, `${m.n_agree} / ${m.n_matches}`);
      return tr;
    };
    body.replaceChildren(
      ...report.advisors.map((a) => row(`participant #${a.participant_id}`, a.conformance,
        a.participant_id)),
      row("pooled verdict", report.conformance, null));
  }

  // The table's columns are its header's (an imported policy's has no R, F, z or V).
  function showCandidates(table, report, urls, open) {
    const columns = [...table.querySelectorAll("th[data-sort]")].map((th) => th.dataset.sort);
    const key = table.dataset.sortKey || "id";
    const sign = table.dataset.sortDir === "desc" ? -1 : 1;
    const rows = [...report.candidates].sort((a, b) => sign * (a[key] - b[key]));
    table.querySelector("tbody").replaceChildren(...rows.map((c) => {
      const row = document.createElement("tr");
      const link = document.createElement("a");
      link.href = urls.full(c.id);
      link.textContent = `#${c.id}`;
      link.addEventListener("click", (e) => { e.preventDefault(); open(urls.full(c.id), `#${c.id}`); });
      cell(row, link);
      // env_return is null in reports stored before the return judge
      for (const col of columns.slice(1)) cell(row, c[col] === null ? "–" : c[col].toFixed(3));
      return row;
    }));
    for (const th of table.querySelectorAll("th[data-sort]")) {
      th.setAttribute("aria-sort", th.dataset.sort !== key ? "none" :
        (sign > 0 ? "ascending" : "descending"));
    }
  }

  function singleRun(root) {
    const api = root.dataset.api;
    const steps = root.dataset.checkpoints.split(",").filter(Boolean).map(Number);
    if (steps.length === 0) return;
    const urls = {
      thumb: (id) => ACV.thumbUrl(root.dataset.thumbTemplate, id),
      full: (id) => ACV.thumbUrl(root.dataset.imageTemplate, id),
    };
    const dialog = document.getElementById("preview");
    const open = (url, caption) => {
      document.getElementById("preview-img").src = url;
      document.getElementById("preview-img").alt = caption;
      document.getElementById("preview-caption").textContent = caption;
      if (typeof dialog.showModal === "function") dialog.showModal();
    };
    const slider = document.getElementById("checkpoint");
    const judgeBox = document.getElementById("judge");
    const human = getJson(`${api}/advice-tree`);
    let curve = null, candidates = null, current = Number(root.dataset.selected), request = 0;
    for (const th of document.querySelectorAll("#candidates th[data-sort]")) {
      th.querySelector("button").addEventListener("click", () => {
        const table = document.getElementById("candidates");
        const same = table.dataset.sortKey === th.dataset.sort;
        table.dataset.sortDir = same && table.dataset.sortDir !== "desc" ? "desc" : "asc";
        table.dataset.sortKey = th.dataset.sort;
        if (candidates) showCandidates(table, candidates, urls, open);
      });
    }
    const judge = () => judgeBox.value;

    function drawCurve() {
      if (!curve) return;
      acvPlots.lines(document.getElementById("chart-curve"), [
        { label: "match agreement", points: curve.map((c) => [c.checkpoint, c.match_agreement]) },
        { label: "Kendall tau-b", points: curve.map((c) => [c.checkpoint,
          c.kendall_tau_b === null ? NaN : c.kendall_tau_b]) },
      ], { xlabel: "timesteps", ylabel: "conformance", yDomain: [-1, 1], selectedX: current,
        onPick: (x) => select(x) });
    }

    function exportLinks(step) {
      for (const a of root.querySelectorAll("#exports a[data-export]")) {
        const all = a.dataset.all === "1";
        a.href = `${api}/${a.dataset.export}?judge=${judge()}` +
          (all ? "" : `&checkpoint=${step}`);
        if (a.dataset.export !== "report.html") a.setAttribute("download", "");
      }
    }

    async function select(step) {
      const mine = ++request;
      current = step;
      slider.value = String(steps.indexOf(step));
      document.getElementById("checkpoint-value").textContent = String(step);
      document.getElementById("agent-title").textContent = `(step ${step})`;
      history.replaceState(null, "", `?checkpoint=${step}&judge=${judge()}`);
      exportLinks(step);
      drawCurve();
      const verdictBox = document.getElementById("verdict");
      try {
        const query = `checkpoint=${step}&judge=${judge()}`;
        const pending = () => { if (mine === request) verdictBox.textContent =
          `Checkpoint ${step} is still computing; this page updates when it is ready.`; };
        const [h, agent, report] = await Promise.all([human,
          getJson(`${api}/agent-tree?${query}`, pending),
          getJson(`${api}/checkpoint-report?${query}`, pending)]);
        if (mine !== request) return;  // a later checkpoint was picked meanwhile
        const m = report.conformance;
        const marks = { human: new Set(report.highlights.human),
          agent: new Set(report.highlights.agent) };
        const opts = { thumb: THUMB, imageUrl: urls.thumb };
        const pick = (doc) => (id) => open(urls.full(id), `#${id} (${doc})`);
        ACVTree.drawPreferenceTree(document.getElementById("human-tree"), h,
          Object.assign({}, opts, { highlight: marks.human, onSelect: pick("human tree") }));
        ACVTree.drawPreferenceTree(document.getElementById("agent-tree"), agent,
          Object.assign({}, opts, { highlight: marks.agent, onSelect: pick("agent tree") }));
        verdictBox.textContent = report.verdict;
        showJudges(document.getElementById("judges-body"), report);
        showAdvisors(document.getElementById("advisors-body"), report);
        candidates = report;
        showCandidates(document.getElementById("candidates"), report, urls, open);
        verdictBox.classList.toggle("all-kept", m.rejected.length === 0);
        showMetrics(root, m);
        drawRejected(document.getElementById("rejected"), m, root.dataset.who, urls, open);
        root.dataset.loaded = `${step}:${judge()}`;
      } catch (err) {
        verdictBox.textContent = `The comparison could not be loaded: ${err.message}`;
      }
    }

    slider.addEventListener("input", () => {
      document.getElementById("checkpoint-value").textContent = String(steps[Number(slider.value)]);
    });
    slider.addEventListener("change", () => select(steps[Number(slider.value)]));
    const loadCurve = () => {
      const asked = judge();
      return getJson(`${api}/conformance-curve?judge=${asked}`, () => {
        document.getElementById("chart-curve").textContent = "Computing…"; })
        .then((c) => {
          if (asked !== judge()) return;  // another judge was picked meanwhile
          curve = c;
          drawCurve();
          root.dataset.curveJudge = asked;
        })
        .catch((err) => { document.getElementById("chart-curve").textContent = err.message; });
    };
    judgeBox.addEventListener("change", () => { select(current); loadCurve(); });
    select(current);
    loadCurve();
  }

  async function severalRuns(root) {
    const rows = [...root.querySelectorAll("tr[data-run-id]")];
    const series = [];
    for (const row of rows) {
      try {
        const curve = await getJson(`/api/runs/${row.dataset.runId}/conformance-curve`);
        series.push({ label: row.dataset.label,
          points: curve.map((c) => [c.checkpoint, c.match_agreement]) });
      } catch (err) {
        // A run without checkpoints has no curve yet.
      }
    }
    const box = document.getElementById("chart-runs");
    if (series.some((s) => s.points.length > 0)) {
      acvPlots.lines(box, series, { xlabel: "timesteps", ylabel: "match agreement",
        yDomain: [0, 1] });
    } else {
      box.textContent = "No run has a checkpoint yet.";
    }
  }

  const single = document.getElementById("compare");
  if (single) singleRun(single);
  const several = document.getElementById("compare-runs");
  if (several) severalRuns(several);
})();
