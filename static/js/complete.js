// The end of an open link's study or survey: after a moment (to read the completion code),
// send the person to the researcher's completion URL (e.g. the crowd platform's).
// A visible #complete-link starts at once (a study's thank-you page); a hidden one waits for
// ACVComplete.redirectSoon (the survey page shows it when the last screen is answered).
"use strict";

window.ACVComplete = {
  redirectSoon(link) {
    const delay = Number(link.dataset.redirectMs) || 0;
    window.setTimeout(() => window.location.assign(link.href), delay);
  },
};

(function () {
  const link = document.getElementById("complete-link");
  if (link && !link.closest("[hidden]")) window.ACVComplete.redirectSoon(link);
})();
