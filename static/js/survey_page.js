// A survey's researcher page: draws each stimulus's two trees and invites respondents.
/* global ACV, ACVSurvey */
"use strict";

(function () {
  const root = document.getElementById("survey-page");
  if (!root) return;
  const id = root.dataset.surveyId, template = root.dataset.thumbTemplate;
  const showHighlights = root.dataset.highlights === "true";

  async function drawStimuli() {
    const result = await ACV.api("GET", `/api/surveys/${id}`);
    if (result.status !== 200) return;
    for (const stimulus of result.data.stimuli) {
      const section = root.querySelector(`[data-stimulus-id="${stimulus.id}"]`);
      stimulus.trees.forEach((tree, i) => {
        const shown = Object.assign({}, tree, { highlight: showHighlights ? tree.highlight : [] });
        ACVSurvey.drawTree(section.querySelector(`[data-tree="${i}"]`), shown, template, 56);
      });
    }
  }

  document.getElementById("add-respondents").addEventListener("click", async () => {
    const message = document.getElementById("add-message");
    const count = Number(document.getElementById("count").value);
    const result = await ACV.api("POST", `/api/surveys/${id}/respondents`, { count });
    if (result.status === 201) {
      window.location.reload();
    } else {
      message.textContent = `Could not invite: ${ACV.errorText(result)}`;
    }
  });
  for (const input of root.querySelectorAll("td.invite input")) {
    input.addEventListener("focus", () => input.select());
  }
  drawStimuli();
})();
