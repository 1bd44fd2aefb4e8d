// Draws an acv.tree/1 Preference Tree as SVG with candidate thumbnails at the nodes.
// Layout: d3-hierarchy's tidy tree (vendored in static/vendor), never a hand-rolled layout.
/* global d3 */
"use strict";

const SVG_NS = "http://www.w3.org/2000/svg";
let treesDrawn = 0;

function svgEl(name, attrs) {
  const el = document.createElementNS(SVG_NS, name);
  for (const [k, v] of Object.entries(attrs || {})) el.setAttribute(k, v);
  return el;
}

// Root the tree's flat node list (pre-order, parent links) with d3.stratify, children ordered
// as in the file (latest round first), so the same tree always draws the same way.
function hierarchy(doc) {
  return d3.stratify()
    .id((n) => String(n.state))
    .parentId((n) => (n.parent === null ? null : String(n.parent)))(doc.tree.nodes);
}

// Draw `doc` into `container`.
// options.imageUrl(candidateId) -> thumbnail URL; options.highlight: Set of candidate ids;
// options.thumb: thumbnail size in px; options.onSelect(candidateId) on click.
function drawPreferenceTree(container, doc, options) {
  const opts = Object.assign({ thumb: 72, highlight: new Set() }, options || {});
  const root = hierarchy(doc);
  const dx = opts.thumb + 18;  // horizontal spacing between siblings
  const dy = opts.thumb + 64;  // vertical spacing between depths: node label, edge, weight
  d3.tree().nodeSize([dx, dy])(root);
  let x0 = Infinity, x1 = -Infinity;
  root.each((d) => { x0 = Math.min(x0, d.x); x1 = Math.max(x1, d.x); });
  const width = x1 - x0 + dx, height = root.height * dy + opts.thumb + 40;
  const scale = fitScale(width, container.clientWidth);
  // A tree whose nodes can be chosen is a group of buttons; otherwise one picture (a role
  // of "img" would hide the buttons from assistive technology).
  const svg = svgEl("svg", {
    viewBox: `${x0 - dx / 2} ${-opts.thumb / 2 - 8} ${width} ${height}`,
    width: width * scale, height: height * scale, class: "pref-tree",
    role: opts.onSelect ? "group" : "img", "aria-label": `Preference tree judged by ${doc.judge}`,
  });
  for (const link of root.links()) svg.appendChild(edge(link, opts));
  for (const d of root.descendants()) svg.appendChild(node(d, opts));
  const words = described(root, opts);
  words.id = `tree-words-${++treesDrawn}`;  // unique: a page may draw many trees
  svg.setAttribute("aria-describedby", words.id);
  container.replaceChildren(svg, words);
  if (!opts.onSelect && !container.hasAttribute("tabindex")) {
    // Its nodes take no focus here, so the box does: a tree wider than it scrolls from the
    // keyboard too (WCAG 2.1.1; axe's scrollable-region-focusable).
    for (const [name, value] of [["tabindex", 0], ["role", "region"],
      ["aria-label", svg.getAttribute("aria-label")]]) container.setAttribute(name, value);
  }
  // A tree still wider than its box starts scrolled so that the champion is in view.
  container.scrollLeft = Math.max(0, (root.x - x0 + dx / 2) * scale -
    container.clientWidth / 2);
  return svg;
}

// The tree in words, for screen readers (WCAG 1.1.1): the champion, whom each state beat,
// and the highlighted states (drawn only by colour and stroke).
function described(root, opts) {
  const name = (d) => `#${d.id}`;
  const sentences = [`The champion is ${name(root)}.`];
  for (const d of root.descendants()) {
    if (d.children) sentences.push(`${name(d)} beat ${d.children.map(name).join(", ")}.`);
  }
  if (opts.highlight.size) {
    sentences.push(`Highlighted: ${[...opts.highlight].map((id) => `#${id}`).join(", ")}.`);
  }
  const words = document.createElement("p");
  words.className = "visually-hidden";
  words.textContent = sentences.join(" ");
  return words;
}

// Shrink a tree wider than its box to fit it, down to MIN_SCALE (thumbnails stay
// recognisable); wider still, the box scrolls. A box not laid out yet (width 0) keeps 1.
const MIN_SCALE = 0.6;
function fitScale(width, boxWidth) {
  const room = boxWidth - 20;  // the box's padding and a scroll bar
  if (room <= 0 || width <= room) return 1;
  return Math.max(MIN_SCALE, room / width);
}

// An edge from below the parent's label to the child's top, its weight w = h(parent) -
// h(child) at the middle (drawn with a halo so that it stays legible over the line).
function edge(link, opts) {
  const id = Number(link.target.id);
  const g = svgEl("g", { class: "edge" + (opts.highlight.has(id) ? " rejected" : "") });
  const x1 = link.source.x, y1 = link.source.y + opts.thumb / 2 + 20;
  const x2 = link.target.x, y2 = link.target.y - opts.thumb / 2 - 3;
  g.appendChild(svgEl("line", { x1, y1, x2, y2 }));
  const label = svgEl("text", { x: (x1 + x2) / 2, y: (y1 + y2) / 2 + 4, class: "weight" });
  label.textContent = `w=${link.target.data.weight}`;
  g.appendChild(label);
  return g;
}

function node(d, opts) {
  const id = Number(d.id), t = opts.thumb;
  const g = svgEl("g", { class: "node" + (d.depth === 0 ? " champion" : "") +
    (opts.highlight.has(id) ? " rejected" : ""),
    transform: `translate(${d.x},${d.y})`, "data-state": id });
  const title = svgEl("title");
  title.textContent = `state ${id}: won ${d.data.height} round(s), depth ${d.data.depth}, ` +
    `T_r = ${d.data.reward.toFixed(2)}`;
  g.appendChild(title);
  if (opts.onSelect) selectable(g, title.textContent, () => opts.onSelect(id));
  g.appendChild(svgEl("rect", { x: -t / 2 - 2, y: -t / 2 - 2, width: t + 4, height: t + 4,
    rx: 6 }));
  if (opts.imageUrl) {
    g.appendChild(svgEl("image", { href: opts.imageUrl(id), x: -t / 2, y: -t / 2,
      width: t, height: t }));
  }
  const label = svgEl("text", { y: t / 2 + 14, class: "label" });
  label.textContent = `#${id} · h${d.data.height}`;
  g.appendChild(label);
  return g;
}

// A node that can be chosen: a button for the keyboard (Enter or Space) as for the mouse.
function selectable(g, label, select) {
  for (const [name, value] of [["tabindex", 0], ["role", "button"], ["aria-label", label]]) {
    g.setAttribute(name, value);
  }
  g.addEventListener("click", select);
  g.addEventListener("keydown", (event) => {
    if (event.key === "Enter" || event.key === " ") {
      event.preventDefault();
      select();
    }
  });
}

window.ACVTree = { drawPreferenceTree };
