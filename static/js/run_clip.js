// A run's clip on the run and compare pages (issue 41 §3), loaded lazily: each
// <figure class="run-clip" data-clip-url data-still-url> starts when it scrolls into view,
// asks for the clip (202 while it renders: asked again after Retry-After, backing off, for
// at most 2 minutes), then shows it. Pause swaps the animation for its still (WCAG 2.2.2);
// with prefers-reduced-motion the still shows until Play. Without JavaScript the figure
// holds a plain link to the clip.
(function () {
  "use strict";

  const GIVE_UP_MS = 120000;
  const MAX_DELAY_MS = 10000;

  function retryAfterMs(response, fallback) {
    const seconds = Number(response.headers.get("Retry-After"));
    return Number.isFinite(seconds) && seconds > 0 ? Math.max(seconds * 1000, fallback) : fallback;
  }

  async function detail(response) {
    try {
      const body = await response.json();
      return typeof body.detail === "string" ? body.detail : "";
    } catch (_) {
      return "";
    }
  }

  function start(figure) {
    const img = figure.querySelector(".run-clip-img");
    const status = figure.querySelector(".run-clip-status");
    const toggle = figure.querySelector(".run-clip-toggle");
    const clipUrl = figure.dataset.clipUrl;
    const stillUrl = figure.dataset.stillUrl;
    const reduced = window.matchMedia("(prefers-reduced-motion: reduce)").matches;
    let playing = !reduced;
    const began = Date.now();

    function say(text, state) {
      status.textContent = text;
      figure.dataset.state = state;
    }

    function show() {
      const src = playing ? clipUrl : stillUrl;
      img.addEventListener("load", function loaded() {
        img.removeEventListener("load", loaded);
        img.hidden = false;
        figure.dataset.state = playing ? "playing" : "paused";
        status.textContent = playing ? "" : "Paused: the clip's middle frame.";
      });
      img.src = src;
      toggle.textContent = playing ? "Pause" : "Play";
      toggle.hidden = false;
    }

    toggle.addEventListener("click", function () {
      playing = !playing;
      show();
    });

    async function poll(delay) {
      let response;
      try {
        response = await fetch(clipUrl, { credentials: "same-origin" });
      } catch (_) {
        response = null;
      }
      if (response && response.status === 200) {
        show();
        return;
      }
      if (response && response.status !== 202) {
        const why = await detail(response);
        say("No clip: " + (why || "the server answered " + response.status) + ".", "failed");
        return;
      }
      if (Date.now() - began > GIVE_UP_MS) {
        say("The clip is taking more than 2 minutes to render: reload the page later.", "failed");
        return;
      }
      const next = response ? retryAfterMs(response, delay) : delay;
      window.setTimeout(function () {
        poll(Math.min(next * 1.5, MAX_DELAY_MS));
      }, next);
    }

    say("Rendering the clip…", "rendering");
    poll(1000);
  }

  function init() {
    const figures = Array.from(document.querySelectorAll("figure.run-clip[data-clip-url]"));
    if (!("IntersectionObserver" in window)) {
      figures.forEach(start);
      return;
    }
    const observer = new IntersectionObserver(function (entries) {
      entries.forEach(function (entry) {
        if (entry.isIntersecting) {
          observer.unobserve(entry.target);
          start(entry.target);
        }
      });
    }, { rootMargin: "100px" });
    figures.forEach(function (figure) {
      figure.dataset.state = "waiting";
      observer.observe(figure);
    });
  }

  if (document.readyState === "loading") {
    document.addEventListener("DOMContentLoaded", init);
  } else {
    init();
  }
})();
