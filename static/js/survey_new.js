// New-survey form: questions (the paper's or the researcher's own), stimuli whose two trees
// come from menus or files, options; posts the JSON body of POST /api/surveys.
/* global ACV */
"use strict";

(function () {
  const form = document.getElementById("survey-form");
  if (!form) return;
  const $ = (id) => document.getElementById(id);
  const field = (root, name) => root.querySelector(`[data-field="${name}"]`);

  // Show the labels (`data-for`) that belong to the chosen kind only.
  function showFor(root, kind) {
    for (const el of root.querySelectorAll("[data-for]")) {
      el.hidden = el.dataset.for !== kind &&
        !(el.dataset.for === "expected" && (kind === "choice" || kind === "yesno"));
    }
  }

  function fillJudges(picker) {
    const option = field(picker, "checkpoint").selectedOptions[0];
    const judges = option && option.dataset.judges ? option.dataset.judges.split(",") : [];
    field(picker, "judge").replaceChildren(...judges.map((j) => new Option(j, j)));
  }

  function addStimulus() {
    const item = $("stimulus-template").content.firstElementChild.cloneNode(true);
    for (const picker of item.querySelectorAll(".tree-source")) {
      const kind = field(picker, "kind");
      kind.addEventListener("change", () => showFor(picker, kind.value));
      field(picker, "checkpoint").addEventListener("change", () => fillJudges(picker));
      fillJudges(picker);
      showFor(picker, kind.value);
    }
    item.querySelector(".remove").addEventListener("click", () => item.remove());
    $("stimulus-list").appendChild(item);
  }

  function addQuestion() {
    const item = $("question-template").content.firstElementChild.cloneNode(true);
    const kind = field(item, "kind");
    kind.addEventListener("change", () => showFor(item, kind.value));
    showFor(item, kind.value);
    item.querySelector(".remove").addEventListener("click", () => item.remove());
    $("question-list").appendChild(item);
  }

  async function treeBody(picker) {
    const kind = field(picker, "kind").value;
    if (kind === "participant") {
      return { kind, participant_id: Number(field(picker, "participant_id").value) };
    }
    if (kind === "run") {
      const [run, step] = field(picker, "checkpoint").value.split(":").map(Number);
      return { kind, run_id: run, checkpoint: step, judge: field(picker, "judge").value };
    }
    const file = field(picker, "file").files[0];
    if (!file) throw new Error(`choose a file for ${picker.querySelector("legend").textContent}`);
    const study = field(picker, "study_id").value;
    return { kind, doc: JSON.parse(await file.text()), study_id: study ? Number(study) : null };
  }

  function questionBody(item) {
    const kind = field(item, "kind").value;
    const expected = field(item, "expected").value.trim();
    return {
      kind, text: field(item, "text").value,
      options: kind === "choice" ? field(item, "options").value.split("\n")
        .map((o) => o.trim()).filter(Boolean) : [],
      points: Number(field(item, "points").value),
      expected: expected && (kind === "choice" || kind === "yesno") ? expected : null,
      confidence: field(item, "confidence").checked,
    };
  }

  async function body() {
    const template = form.querySelector("input[name=template]:checked").value;
    const stimuli = [];
    for (const item of $("stimulus-list").children) {
      const [one, two] = item.querySelectorAll(".tree-source");
      stimuli.push({ label: field(item, "label").value,
                     tree1: await treeBody(one), tree2: await treeBody(two) });
    }
    const seed = $("seed").value.trim();
    return {
      name: $("name").value, intro: $("intro").value, template,
      paper_terms: { tree1: $("term1").value, tree2: $("term2").value },
      questions: template === "blank" ? [...$("question-list").children].map(questionBody) : [],
      stimuli,
      attention_check: $("attention").checked ? { question: "q1", expected: "same" } : null,
      highlights: $("highlights").checked,
      assignment: form.querySelector("input[name=assignment]:checked").value,
      seed: seed === "" ? null : Number(seed),
    };
  }

  function showError(text) {
    $("form-error").textContent = text;
    $("form-error").hidden = false;
    $("form-error").scrollIntoView({ block: "center" });
  }

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    $("create").disabled = true;
    try {
      const result = await ACV.api("POST", "/api/surveys", await body());
      if (result.status === 201) {
        window.location.assign(`/surveys/${result.data.id}`);
        return;
      }
      showError(`Could not create the survey: ${ACV.errorText(result)}`);
    } catch (err) {
      showError(`Could not create the survey: ${err.message}`);
    }
    $("create").disabled = false;
  });

  for (const radio of form.querySelectorAll("input[name=template]")) {
    radio.addEventListener("change", () => {
      const blank = radio.value === "blank" && radio.checked;
      $("blank-questions").hidden = !blank;
      $("paper-terms").hidden = blank;
      if (blank && !$("question-list").children.length) addQuestion();
    });
  }
  $("add-stimulus").addEventListener("click", addStimulus);
  $("add-question").addEventListener("click", addQuestion);
  addStimulus();
  form.dataset.ready = "true"; // the controls above answer from now on (tests wait for it)
})();
