// Charts of the run and comparison pages, drawn with Observable Plot (static/vendor/plot.umd.min.js,
// on d3). One entry point: acvPlots.lines(container, series, options). Colours come from
// classes (s0..s4 in runs.css), not from Plot, so that the page's palette stays in CSS. Each
// series also has its own dash pattern, shown in its legend key too: lines are told apart
// without colour (WCAG 1.4.1), and 5 colours times 4 patterns never repeat below 20 series.
//
// The pages' policy forbids inline <style> elements: Plot puts one in every SVG it draws, so
// it is removed before the SVG joins the page, and its rules live in runs.css (.acv-plot).
/* global Plot */
"use strict";

(function () {
  const HEIGHT = 260;
  const CLASS = "acv-plot";
  const DENSE = 60;  // a series with more points than this is drawn without dots
  const DASHES = ["none", "7 3", "2 3", "9 3 2 3"];  // stroke-dasharray by series
  const NS = "http://www.w3.org/2000/svg";

  const finite = (points) => points.filter((p) => Number.isFinite(p[1]));
  const label = (s, p) => `${s.label}: ${+p[1].toFixed(3)} at ${p[0]}`;
  const colour = (i) => `s${i % 5}`;
  const dash = (i) => DASHES[i % DASHES.length];

  // The marks of series `i`: its band, its line (gaps where y is not finite) and its dots.
  function seriesMarks(s, i, o) {
    const cls = colour(i), marks = [];
    if (s.band && s.band.length > 1) {
      marks.push(Plot.areaY(s.band, { x: (b) => b[0], y1: (b) => b[1], y2: (b) => b[2],
        className: `band ${cls}` }));
    }
    const points = s.points.map((p) => [p[0], Number.isFinite(p[1]) ? p[1] : undefined]);
    marks.push(Plot.lineY(points, { x: (p) => p[0], y: (p) => p[1], className: `line ${cls}`,
      strokeDasharray: dash(i) }));
    if (s.points.length <= DENSE || o.onPick) {
      marks.push(Plot.dot(finite(s.points), { x: (p) => p[0], y: (p) => p[1],
        r: o.onPick ? 5 : 3, title: (p) => label(s, p),
        className: `dot ${cls} series-${i}` + (o.onPick ? " pickable" : "") }));
    }
    return marks;
  }

  // The dots a click opens: circle k of series i's dot group is its k-th finite point.
  function wirePicks(svg, series, o) {
    if (!o.onPick) return;
    series.forEach((s, i) => {
      const points = finite(s.points);
      const dots = svg.querySelectorAll(`g.dot.series-${i} circle`);
      dots.forEach((dot, k) => {
        dot.classList.add("dot", colour(i), "pickable");
        if (points[k][0] === o.selectedX) dot.classList.add("selected");
        dot.addEventListener("click", () => o.onPick(points[k][0]));
      });
    });
  }

  // Its key: a short line in the series' colour and dash pattern.
  function legendKey(i) {
    const key = document.createElementNS(NS, "svg");
    key.setAttribute("class", "key");
    key.setAttribute("viewBox", "0 0 28 8");
    key.setAttribute("aria-hidden", "true");
    const line = key.appendChild(document.createElementNS(NS, "line"));
    line.setAttribute("class", colour(i));
    for (const [name, value] of [["x1", 0], ["y1", 4], ["x2", 28], ["y2", 4]]) {
      line.setAttribute(name, value);
    }
    line.setAttribute("stroke-dasharray", dash(i));
    return key;
  }

  function legend(series) {
    const list = document.createElement("ul");
    list.className = "plot-legend";
    series.forEach((s, i) => {
      const item = list.appendChild(document.createElement("li"));
      item.append(legendKey(i), s.label);
    });
    return list;
  }

  // Draw `series` ([{label, points: [[x, y]], band: [[x, lo, hi]]}]) into `container`.
  // options: xlabel, ylabel, yDomain [lo, hi], selectedX, onPick(x) (dots become clickable).
  function lines(container, series, options) {
    const o = options || {};
    const svg = Plot.plot({
      className: CLASS, width: Math.max(320, Math.round(container.clientWidth || 640)),
      height: HEIGHT, marginLeft: 52, ariaLabel: o.ylabel || "chart",
      x: { label: o.xlabel || null, tickFormat: "~s" },
      y: { label: o.ylabel || null, domain: o.yDomain, grid: true, nice: !o.yDomain },
      marks: series.flatMap((s, i) => seriesMarks(s, i, o)),
    });
    for (const style of svg.querySelectorAll("style")) style.remove();  // before it joins
    // One image with one name: Plot's labels on inner groups are not allowed on them (ARIA).
    svg.setAttribute("role", "img");
    for (const node of svg.querySelectorAll("[aria-label], [aria-description]")) {
      node.removeAttribute("aria-label");
      node.removeAttribute("aria-description");
    }
    wirePicks(svg, series, o);
    container.replaceChildren(...(series.length > 1 ? [legend(series)] : []), svg);
    return svg;
  }

  window.acvPlots = { lines };
})();
