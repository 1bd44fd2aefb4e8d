// Study page: wait for a preparing study, draw each finished participant's Preference Tree
// (acv.tree/1 documents from /api/studies/{id}/trees), and copy invite links.
/* global ACV, ACVTree */
"use strict";

const POLL_MS = 1500;

// While the study is `preparing`, poll its status and reload the page when it changes.
async function waitUntilPrepared(root) {
  for (;;) {
    await new Promise((resolve) => setTimeout(resolve, POLL_MS));
    try {
      const result = await ACV.api("GET", root.dataset.studyUrl);
      if (result.status === 200 && result.data.status !== "preparing") break;
    } catch (err) {
      // The server may be restarting: keep polling.
    }
  }
  window.location.reload();
}

async function drawTrees(root) {
  const boxes = root.querySelectorAll(".tree-box[data-participant-id]");
  if (boxes.length === 0) return;
  let trees = new Map();
  try {
    const result = await ACV.api("GET", root.dataset.treesUrl);
    if (result.status !== 200) throw new Error(ACV.errorText(result));
    trees = new Map(result.data.map((t) => [String(t.participant_id), t.tree]));
  } catch (err) {
    boxes.forEach((box) => { box.textContent = `The trees could not be loaded: ${err.message}`; });
    return;
  }
  const imageUrl = (id) => ACV.thumbUrl(root.dataset.thumbTemplate, id);
  for (const box of boxes) {
    const doc = trees.get(box.dataset.participantId);
    if (doc) ACVTree.drawPreferenceTree(box, doc, { imageUrl });
    else box.textContent = "This tree is not available yet.";
  }
}

// "Copy" buttons next to invite links; falls back to selecting the text.
function wireCopyButtons(root) {
  root.querySelectorAll("td.invite").forEach((cell) => {
    const input = cell.querySelector("input");
    const button = cell.querySelector("button.copy");
    input.addEventListener("focus", () => input.select());
    button.addEventListener("click", async () => {
      input.select();
      try {
        await navigator.clipboard.writeText(input.value);
        button.textContent = "Copied";
      } catch (err) {
        button.textContent = "Press Ctrl+C";
      }
      setTimeout(() => { button.textContent = "Copy"; }, 2000);
    });
  });
}

(function () {
  const root = document.getElementById("study");
  if (!root) return;
  if (root.dataset.status === "preparing") waitUntilPrepared(root);
  wireCopyButtons(root);
  drawTrees(root);
})();
