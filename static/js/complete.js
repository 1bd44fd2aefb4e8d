// The end of an open link's study or survey: after a while (to read and copy the completion
// code), send the person to the researcher's completion URL (e.g. the crowd platform's),
// unless they choose to stay (WCAG 2.2.1: a time limit the person can turn off).
// A visible #complete-link starts at once (a study's thank-you page); a hidden one waits for
// ACVComplete.redirectSoon (the survey page shows it when the last screen is answered).
"use strict";

window.ACVComplete = {
  redirectSoon(link) {
    const delay = Number(link.dataset.redirectMs) || 0;
    const timer = window.setTimeout(() => window.location.assign(link.href), delay);
    const stay = document.getElementById("stay-here");
    if (!stay) return;
    stay.hidden = false;
    stay.addEventListener("click", () => {
      window.clearTimeout(timer);
      document.getElementById("redirect-note").textContent =
        "(you stay here: use the button when you are ready)";
      stay.hidden = true;
      link.focus();  // the button it replaces had the focus
    });
  },
};

(function () {
  const link = document.getElementById("complete-link");
  if (link && !link.closest("[hidden]")) window.ACVComplete.redirectSoon(link);
})();
