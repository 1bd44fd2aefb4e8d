// Draws a survey's trees as the compare page does (static/js/tree.js): thumbnails from the
// study the tree is over (served through the survey, so respondents may see them), weights,
// and the survey's highlights only when it shows them.
/* global ACVTree */
"use strict";

window.ACVSurvey = window.ACVSurvey || {};

// Draw `tree` ({doc, study_id, highlight}) into `box`; `template` has {study} and {id}.
window.ACVSurvey.drawTree = function drawTree(box, tree, template, thumb) {
  const imageUrl = tree.study_id === null ? null : (id) =>
    template.replace("{study}", String(tree.study_id)).replace("{id}", String(id));
  ACVTree.drawPreferenceTree(box, tree.doc, {
    imageUrl, thumb: thumb || 64, highlight: new Set(tree.highlight || []),
  });
};
