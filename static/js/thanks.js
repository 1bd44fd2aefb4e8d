// Thank-you page: fetch the participant's acv.tree/1 document and draw it with tree.js.
/* global ACV, ACVTree */
"use strict";

(async function () {
  const box = document.getElementById("my-tree");
  if (!box) return;
  try {
    const result = await ACV.api("GET", box.dataset.treeUrl);
    if (result.status !== 200) throw new Error(ACV.errorText(result));
    ACVTree.drawPreferenceTree(box, result.data, {
      imageUrl: (id) => ACV.thumbUrl(box.dataset.thumbTemplate, id),
    });
  } catch (err) {
    box.textContent = `Your tree could not be drawn: ${err.message}`;
  }
})();
