// A respondent's survey: the intro, then one screen at a time (two trees, left and right as
// the server planned them, and the questions), then thanks. Answers go to
// POST /api/surveys/me/screens/{position}/answers with the time spent on the screen.
/* global ACV, ACVSurvey, ACVComplete */
"use strict";

(function () {
  const root = document.getElementById("respond");
  if (!root) return;
  const $ = (id) => document.getElementById(id);
  const template = root.dataset.thumbTemplate;
  let current = null, shownAt = 0;

  function show(section) {
    for (const id of ["intro", "screen", "done"]) $(id).hidden = id !== section;
  }

  // A radio button per option, as a big tappable label; `name` groups them.
  function radios(box, name, options, labels) {
    options.forEach((option, i) => {
      const label = document.createElement("label");
      label.className = "choice-button";
      const input = document.createElement("input");
      Object.assign(input, { type: "radio", name, value: option, required: true });
      label.append(input, document.createTextNode(` ${labels ? labels[i] : option}`));
      box.appendChild(label);
    });
  }

  function questionField(q) {
    const item = $("question-template").content.firstElementChild.cloneNode(true);
    item.dataset.key = q.key;
    item.querySelector("legend").textContent = q.text;
    const choices = item.querySelector(".choices");
    if (q.kind === "text") {
      const area = document.createElement("textarea");
      Object.assign(area, { name: q.key, rows: 3, maxLength: 2000 });
      area.setAttribute("aria-label", q.text);
      choices.appendChild(area);
    } else {
      const labels = q.kind === "yesno" ? ["Yes", "No"] : null;
      radios(choices, q.key, q.options, labels);
    }
    if (q.confidence) {
      const conf = item.querySelector(".confidence");
      conf.hidden = false;
      radios(conf.querySelector(".scale"), `${q.key}-confidence`, ["1", "2", "3", "4", "5"]);
    }
    return item;
  }

  function render(screen) {
    current = screen;
    $("position").textContent = screen.position;
    $("total").textContent = screen.total;
    $("answer-error").hidden = true;
    show("screen");
    for (const side of ["left", "right"]) {
      $(`${side}-name`).textContent = screen[side].name;
      ACVSurvey.drawTree($(`tree-${side}`), screen[side], template, 48);
    }
    $("questions").replaceChildren(...screen.questions.map(questionField));
    $("submit").disabled = false;
    root.dataset.position = screen.position;
    root.dataset.ready = "true";
    window.scrollTo(0, 0);
    $("screen-title").focus();  // the control that led here is gone or done: say where we are
    shownAt = performance.now();
  }

  async function next() {
    root.dataset.ready = "false";
    let result;
    try {
      result = await ACV.api("GET", "/api/surveys/me/screen");
    } catch (error) {  // the network: nothing was lost, the same step can be tried again
      show("screen");
      fail("Could not load the next screen: check your connection and reload the page.");
      return;
    }
    if (result.status === 204) {
      show("done");
      await complete();
      root.dataset.finished = "true";
    } else if (result.status === 200) {
      render(result.data);
    } else {
      show("screen");
      fail(`Could not load the next screen: ${ACV.errorText(result)}`);
    }
  }

  // An open-link respondent's completion code and redirect (the server sends them only
  // once every screen is answered).
  async function complete() {
    const result = await ACV.api("GET", "/api/surveys/me");
    if (result.status !== 200) return;
    const { completion_code: code, redirect_url: url } = result.data;
    if (code) {
      $("completion-code").textContent = code;
      $("completion").hidden = false;
    }
    if (url) {
      $("complete-link").href = url;
      $("complete").hidden = false;
      ACVComplete.redirectSoon($("complete-link"));
    }
  }

  function fail(text) {
    $("answer-error").textContent = text;
    $("answer-error").hidden = false;
  }

  // The answers of the screen, or the first question left unanswered.
  function collect() {
    const answers = {};
    for (const q of current.questions) {
      const form = $("answers");
      const value = q.kind === "text" ? form.elements[q.key].value.trim() :
        (form.querySelector(`input[name="${q.key}"]:checked`) || {}).value;
      if (!value) return { missing: q.text };
      const answer = { value };
      if (q.confidence) {
        const conf = form.querySelector(`input[name="${q.key}-confidence"]:checked`);
        if (!conf) return { missing: `your confidence in “${q.text}”` };
        answer.confidence = Number(conf.value);
      }
      answers[q.key] = answer;
    }
    return { answers };
  }

  $("answers").addEventListener("submit", async (event) => {
    event.preventDefault();
    const { answers, missing } = collect();
    if (missing) {
      fail(`Please answer: ${missing}`);
      return;
    }
    $("submit").disabled = true;
    const screenMs = Math.max(0, Math.round(performance.now() - shownAt));
    let result;
    try {
      result = await ACV.api("POST", `/api/surveys/me/screens/${current.position}/answers`,
        { answers, screen_ms: screenMs });
    } catch (error) {  // the network: the answers are still in the form, to send again
      fail("Your answers were not sent: check your connection and press Submit again.");
      $("submit").disabled = false;
      return;
    }
    if (result.status === 201 || result.status === 200) {
      await next();
    } else if (result.status === 409) {  // answered before (another tab): that answer stands
      await next();
      fail("That screen was answered before, in another tab or window; those answers are kept.");
    } else {
      fail(`Your answers were not stored: ${ACV.errorText(result)}`);
      $("submit").disabled = false;
    }
  });

  $("start").addEventListener("click", next);
  if (root.dataset.started === "true" || root.dataset.finished === "true") {
    next();
  } else {
    show("intro");
  }
})();
