// Small SVG line charts for the run and comparison pages: axes with round ticks, one line per
// series (optional band), optional clickable points. Colours come from classes (runs.css).
"use strict";

(function () {
  const NS = "http://www.w3.org/2000/svg";
  const H = 260, M = { left: 52, right: 14, top: 30, bottom: 38 };
  let W = 640;  // set per chart to the container's width, so that text keeps its size

  function el(name, attrs, text) {
    const node = document.createElementNS(NS, name);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    if (text !== undefined) node.textContent = text;
    return node;
  }

  // About `count` round tick values covering [lo, hi].
  function ticks(lo, hi, count) {
    if (hi <= lo) return [lo];
    const raw = (hi - lo) / count, mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(v);
    return out;
  }

  function fmt(v) {
    const a = Math.abs(v);
    if (a >= 1e6) return `${+(v / 1e6).toFixed(2)}M`;
    if (a >= 1e4) return `${+(v / 1e3).toFixed(1)}k`;
    return String(+v.toFixed(3));
  }

  function extent(values, fallback) {
    const finite = values.filter((v) => Number.isFinite(v));
    if (finite.length === 0) return fallback;
    let lo = Math.min(...finite), hi = Math.max(...finite);
    if (lo === hi) { lo -= Math.abs(lo) * 0.1 || 1; hi += Math.abs(hi) * 0.1 || 1; }
    return [lo, hi];
  }

  // Draw `series` ([{label, points: [[x, y]], band: [[x, lo, hi]]}]) into `container`.
  // opts: xlabel, ylabel, yDomain [lo, hi], selectedX, onPick(x) (points become clickable).
  function lineChart(container, series, opts) {
    const o = opts || {};
    W = Math.max(320, Math.round(container.clientWidth || 640));
    const xs = series.flatMap((s) => s.points.map((p) => p[0]));
    const ys = series.flatMap((s) => s.points.map((p) => p[1])
      .concat((s.band || []).flatMap((b) => [b[1], b[2]])));
    const [x0, x1] = extent(xs, [0, 1]);
    const [y0, y1] = o.yDomain || extent(ys, [0, 1]);
    const sx = (x) => M.left + (x - x0) / (x1 - x0) * (W - M.left - M.right);
    const sy = (y) => H - M.bottom - (y - y0) / (y1 - y0) * (H - M.top - M.bottom);
    const svg = el("svg", { viewBox: `0 0 ${W} ${H}`, role: "img",
      "aria-label": o.ylabel || "chart" });
    const grid = svg.appendChild(el("g", { class: "grid" }));
    const axis = svg.appendChild(el("g", { class: "axis" }));
    for (const t of ticks(y0, y1, 5)) {
      grid.appendChild(el("line", { x1: M.left, x2: W - M.right, y1: sy(t), y2: sy(t) }));
      axis.appendChild(el("text", { x: M.left - 6, y: sy(t) + 4, "text-anchor": "end" }, fmt(t)));
    }
    for (const t of ticks(x0, x1, 6)) {
      axis.appendChild(el("text", { x: sx(t), y: H - M.bottom + 16, "text-anchor": "middle" },
        fmt(t)));
    }
    axis.appendChild(el("line", { x1: M.left, x2: W - M.right, y1: H - M.bottom,
      y2: H - M.bottom }));
    axis.appendChild(el("text", { x: (M.left + W - M.right) / 2, y: H - 4,
      "text-anchor": "middle" }, o.xlabel || ""));
    axis.appendChild(el("text", { x: 12, y: (M.top + H - M.bottom) / 2, "text-anchor": "middle",
      transform: `rotate(-90 12 ${(M.top + H - M.bottom) / 2})` }, o.ylabel || ""));
    series.forEach((s, i) => drawSeries(svg, s, `s${i % 5}`, sx, sy, o));
    if (series.length > 1) legend(svg, series);
    container.replaceChildren(svg);
    return svg;
  }

  function drawSeries(svg, s, cls, sx, sy, o) {
    if (s.band && s.band.length > 1) {
      const top = s.band.map((b) => `${sx(b[0])},${sy(b[2])}`);
      const bottom = s.band.slice().reverse().map((b) => `${sx(b[0])},${sy(b[1])}`);
      svg.appendChild(el("polygon", { class: `band ${cls}`, points: top.concat(bottom).join(" ") }));
    }
    // Gaps (null or NaN) split the line into segments.
    let segment = [];
    const flush = () => {
      if (segment.length > 1) {
        svg.appendChild(el("polyline", { class: `line ${cls}`, points: segment.join(" ") }));
      }
      segment = [];
    };
    for (const [x, y] of s.points) {
      if (Number.isFinite(y)) segment.push(`${sx(x)},${sy(y)}`); else flush();
    }
    flush();
    if (s.points.length > 60 && !o.onPick) return;  // dense curves: the line says enough
    for (const [x, y] of s.points) {
      if (!Number.isFinite(y)) continue;
      const dot = el("circle", { cx: sx(x), cy: sy(y), r: o.onPick ? 5 : 3,
        class: `dot ${cls}` + (o.onPick ? " pickable" : "") + (x === o.selectedX ? " selected" : "") });
      dot.appendChild(el("title", {}, `${s.label}: ${fmt(y)} at ${fmt(x)}`));
      if (o.onPick) dot.addEventListener("click", () => o.onPick(x));
      svg.appendChild(dot);
    }
  }

  function legend(svg, series) {
    const g = svg.appendChild(el("g", { class: "legend" }));
    let x = M.left + 8;
    series.forEach((s, i) => {
      g.appendChild(el("rect", { x, y: 8, width: 14, height: 4, class: `dot s${i % 5}` }));
      const label = el("text", { x: x + 18, y: 14 }, s.label);
      g.appendChild(label);
      x += 28 + 6.2 * s.label.length;
    });
  }

  window.ACVChart = { lineChart };
})();
