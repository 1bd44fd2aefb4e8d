// Same-origin JSON calls for the pages. The browser sends the role's HttpOnly cookie; every
// call also carries `X-Requested-With: acv`, which a cross-site form cannot set (CSRF).
"use strict";

window.ACV = window.ACV || {};

// fetch `url` with `method` and an optional JSON `body`; resolves to {status, data} where data
// is the parsed JSON body (null for 204 or a non-JSON answer). Rejects only on network errors.
window.ACV.api = async function api(method, url, body) {
  const headers = { "Accept": "application/json", "X-Requested-With": "acv" };
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const response = await fetch(url, {
    method, headers, credentials: "same-origin", cache: "no-store",
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  let data = null;
  if (response.status !== 204 &&
      (response.headers.get("Content-Type") || "").includes("application/json")) {
    data = await response.json();
  }
  return { status: response.status, data };
};

// A candidate's thumbnail URL from a page's `data-thumb-template` ("{id}" is replaced).
window.ACV.thumbUrl = function thumbUrl(template, candidateId) {
  return template.replace("{id}", String(candidateId));
};

// The text of an API error body ({"detail": ...}) for people: a service's sentence, or a
// validation error's list (422) as "field: what is wrong; ...".
window.ACV.errorText = function errorText(result) {
  const detail = result && result.data && result.data.detail;
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail) && detail.length) {
    return detail.map((d) => `${(d.loc || []).slice(1).join(".") || "the request"}: ${d.msg}`)
      .join("; ");
  }
  return `the server answered ${result ? result.status : "nothing"}`;
};
