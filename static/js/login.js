// Login page: a link `/login#token=...` fills in the admin token and submits the form. The
// fragment never reaches the server, so the token stays out of its logs; it is removed from
// the address bar (and history) at once.
"use strict";

(function () {
  const form = document.getElementById("login-form");
  if (!form) return;
  const fromHash = new URLSearchParams(window.location.hash.slice(1)).get("token");
  const fromQuery = new URLSearchParams(window.location.search).get("token");
  const token = fromHash || fromQuery;
  if (!token) return;
  const query = new URLSearchParams(window.location.search);
  query.delete("token");
  const clean = window.location.pathname + (query.toString() ? `?${query}` : "");
  window.history.replaceState(null, "", clean);
  form.elements.token.value = token;
  form.requestSubmit();
})();
