// Thank-you page of an open-link study: after a moment (to read the completion code), send
// the participant to the researcher's completion URL (e.g. the crowd platform's).
"use strict";

(function () {
  const link = document.getElementById("complete-link");
  if (!link) return;
  const delay = Number(link.dataset.redirectMs) || 0;
  window.setTimeout(() => window.location.assign(link.href), delay);
})();
