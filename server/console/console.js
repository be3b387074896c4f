// npfkct web console: the server's sessions and, for the selected one, its belief map, step
// history and search statistics, refreshed while a robot plays. Plain JavaScript and SVG, served
// by npfkct-server itself (no build step, nothing from the network). Everything it shows comes
// from the public API: GET /v1/sessions, /v1/sessions/{id}, /belief and /steps.
'use strict';

// The colour map of the cell probability: the same stops as the PNG renderer
// (render/src/belief_picture.cc, ColorStops()): pale where the camera saw no target, orange-red
// where it has not looked, dark red where the target is likely.
const COLOR_STOPS = [
  [0.0, 0xee, 0xf3, 0xf8],
  [0.25, 0xfe, 0xe0, 0x8b],
  [0.5, 0xf4, 0x6d, 0x43],
  [1.0, 0x67, 0x00, 0x1f],
];
const COLORS = {
  object: '#646464', target: '#149628', obstacle: '#141414', removed: '#a0a0a0',
  robot: '#145aa0', next: '#962896', furniture: '#dedede', furnitureEdge: '#aaaaaa',
  region: '#aac8e6', ink: '#282828', muted: '#6e6e6e',
};
const REFRESH_MS = 1000;
const SVG_NS = 'http://www.w3.org/2000/svg';

// The session the page's #fragment names ('' when it names none or is not valid percent-encoding:
// a crafted link must not stop the console).
function selectedFromHash() {
  try {
    return decodeURIComponent(location.hash.replace(/^#/, ''));
  } catch (e) {
    return '';
  }
}

// Every session, following nextPageToken (a fleet's store answers at most 100 per page), up to
// MAX_LIST_PAGES pages.
const MAX_LIST_PAGES = 20;
async function listSessions() {
  let sessions = [];
  let token = '';
  for (let page = 0; page < MAX_LIST_PAGES; ++page) {
    const query = token ? `&pageToken=${encodeURIComponent(token)}` : '';
    const list = await api(`/v1/sessions?pageSize=1000${query}`);
    sessions = sessions.concat(list.sessions);
    token = list.nextPageToken || '';
    if (!token) break;
  }
  return sessions;
}

const state = {
  apiKey: sessionStorage.getItem('npfkct.apiKey') || '',
  selected: selectedFromHash(),
  lastSeen: '',        // updateTime + state of the selected session when last drawn
  needsKey: false,
  shown: null,         // the step the timeline shows; null: the latest (live)
  beliefs: new Map(),  // the selected session's beliefs this page saw, by the step they follow
  latest: null,        // {session, belief, steps} of the last refresh
};

// ---- helpers ----

function $(id) { return document.getElementById(id); }

function el(tag, attrs = {}, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function svg(tag, attrs = {}, text) {
  const e = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function sigmoid(x) { return 1 / (1 + Math.exp(-x)); }

function probabilityColor(p) {
  if (!(p >= 0)) p = 0;
  p = Math.min(1, p);
  for (let i = 1; i < COLOR_STOPS.length; i++) {
    const [p1, r1, g1, b1] = COLOR_STOPS[i];
    if (p <= p1) {
      const [p0, r0, g0, b0] = COLOR_STOPS[i - 1];
      const t = (p - p0) / (p1 - p0);
      return [Math.round(r0 + t * (r1 - r0)), Math.round(g0 + t * (g1 - g0)),
              Math.round(b0 + t * (b1 - b0))];
    }
  }
  return COLOR_STOPS[COLOR_STOPS.length - 1].slice(1);
}

function rgb(c) { return `rgb(${c[0]},${c[1]},${c[2]})`; }

function fmt(x, digits = 0) {
  if (x === undefined || x === null || Number.isNaN(x)) return '–';
  return Number(x).toLocaleString('en-US', {minimumFractionDigits: digits,
                                            maximumFractionDigits: digits});
}

function meanOdds(o) { return o.faceLogOdds.reduce((a, b) => a + b, 0) / o.faceLogOdds.length; }

async function api(path) {
  const headers = {};
  if (state.apiKey) headers.Authorization = 'Bearer ' + state.apiKey;
  const res = await fetch(path, {headers, cache: 'no-store'});
  if (res.status === 401) {
    state.needsKey = true;
    throw new Error('unauthenticated');
  }
  if (!res.ok) {
    let message = res.statusText;
    try { message = (await res.json()).error.message; } catch (e) { /* not JSON */ }
    throw new Error(`${res.status}: ${message}`);
  }
  return res.json();
}

// ---- sessions ----

function describePlanner(p) {
  if (p.name !== 'npfkct') return p.name;
  return p.model ? `npfkct, model ${p.model}` : 'npfkct, uniform candidates';
}

function renderSessions(sessions) {
  const list = $('sessions');
  list.replaceChildren();
  $('no-sessions').classList.toggle('hidden', sessions.length > 0);
  for (const s of sessions) {
    const li = el('li', {'data-id': s.id});
    if (s.id === state.selected) li.classList.add('selected');
    li.append(el('div', {class: 'sid'}, s.id.slice(0, 12) + '…'),
              el('div', {}, s.displayName || '(no name)'),
              el('div', {class: 'muted'}, `${describePlanner(s.planner)} · step ${s.step} · ` +
                 s.state.toLowerCase().replace('_', ' ')));
    li.addEventListener('click', () => select(s.id));
    list.append(li);
  }
}

function select(id) {
  state.selected = id;
  state.lastSeen = '';
  state.shown = null;
  state.beliefs = new Map();
  history.replaceState(null, '', '#' + encodeURIComponent(id));
  refresh();
}

// ---- the belief map ----

function boxCorners(box) {
  // Box corners in the order of the server (index bit 0: +x/-x, bit 1: +y/-y), as a footprint
  // polygon: corners 0, 1, 3, 2.
  const [cx, cy] = box.center, [sx, sy] = box.size, c = Math.cos(box.yaw), s = Math.sin(box.yaw);
  const corner = (i) => {
    const lx = (i & 1 ? 0.5 : -0.5) * sx, ly = (i & 2 ? 0.5 : -0.5) * sy;
    return [cx + c * lx - s * ly, cy + s * lx + c * ly];
  };
  return [0, 1, 2, 3].map(corner);
}

function points(poly) { return poly.map(([x, y]) => `${x},${y}`).join(' '); }

function heatImage(ws) {
  const canvas = document.createElement('canvas');
  canvas.width = ws.cellsX;
  canvas.height = ws.cellsY;
  const ctx = canvas.getContext('2d');
  const image = ctx.createImageData(ws.cellsX, ws.cellsY);
  for (let iy = 0; iy < ws.cellsY; iy++) {
    for (let ix = 0; ix < ws.cellsX; ix++) {
      const c = probabilityColor(sigmoid(ws.logOdds[iy * ws.cellsX + ix]));
      const k = 4 * (iy * ws.cellsX + ix);
      image.data[k] = c[0];
      image.data[k + 1] = c[1];
      image.data[k + 2] = c[2];
      image.data[k + 3] = 255;
    }
  }
  ctx.putImageData(image, 0, 0);
  return canvas.toDataURL('image/png');
}

function robotShape(group, config, radius, footprint, frustum, color, dashed, unit) {
  const g = svg('g', {class: dashed ? 'next-view' : 'robot'});
  const dash = dashed ? {'stroke-dasharray': `${4 * unit} ${3 * unit}`} : {};
  g.append(svg('polygon', {points: points(frustum), fill: color,
                           'fill-opacity': dashed ? 0.1 : 0.16, stroke: color,
                           'stroke-width': unit, ...dash}));
  if (footprint) {  // the base's outline at its heading
    const c = Math.cos(config.yaw), s = Math.sin(config.yaw);
    g.append(svg('polygon', {points: points(footprint.map(([x, y]) =>
                               [config.x + c * x - s * y, config.y + s * x + c * y])),
                             fill: 'none', stroke: color, 'stroke-width': 2 * unit, ...dash}));
  } else {
    g.append(svg('circle', {cx: config.x, cy: config.y, r: radius, fill: 'none', stroke: color,
                            'stroke-width': 2 * unit, ...dash}));
  }
  const l = Math.max(0.25, 0.8 * radius);
  g.append(svg('line', {x1: config.x, y1: config.y, x2: config.x + l * Math.cos(config.yaw),
                        y2: config.y + l * Math.sin(config.yaw), stroke: color,
                        'stroke-width': 2.5 * unit}));
  group.append(g);
}

// Where the target probably is: a declared target, an object whose faces look like the target
// (P >= 0.6), else the workspace with most of the grid world's mass (as the PNG's legend says).
function bestGuess(belief, session, steps) {
  if (session && session.state === 'DONE') {
    const last = [...(steps || [])].reverse().find((s) => s.outcome && s.outcome.done);
    const id = last && last.action.objectId;
    return {text: id ? `found: ${id}, removed at step ${last.step}` : 'found: the target was removed',
            object: id};
  }
  let best = null;
  for (const o of belief.objects) {
    if (o.status === 'DECLARED_TARGET') return {text: `declared target: ${o.id}`, object: o.id};
    if (o.status === 'REMOVED') continue;
    const p = sigmoid(meanOdds(o));
    if (!best || p > best.p) best = {p, o};
  }
  if (best && best.p >= 0.6) {
    return {text: `object ${best.o.id} (P ${best.p.toFixed(2)})`, object: best.o.id};
  }
  let ws = null;
  for (const w of belief.grid.workspaces) {
    if (!ws || (w.targetMass || 0) > (ws.targetMass || 0)) ws = w;
  }
  if (!ws) return {text: 'unknown'};
  return {text: `on ${ws.name} (${Math.round(100 * (ws.targetMass || 0))}% of the mass)`,
          workspace: ws.name};
}

// The map's height: what the window leaves below its top edge (the SVG keeps the view's aspect
// and centres it), so the whole view is in sight without scrolling.
function fitMap() {
  const map = $('map');
  const top = map.getBoundingClientRect().top + window.scrollY;
  map.style.height = `${Math.max(320, Math.floor(window.innerHeight - top - 12))}px`;
}

function renderMap(belief, guess, shown) {
  const map = $('map');
  fitMap();
  for (const child of [...map.children]) {
    if (child.tagName !== 'title' && child.tagName !== 'desc') child.remove();
  }
  // The server's crop of the belief, grown to hold the robot's path up to the step shown.
  let [x0, y0] = belief.view.min, [x1, y1] = belief.view.max;
  const reach = (belief.robotRadius || 0.3) + 0.1;
  for (const p of [...shown.path.filter((q) => q.robotState).map((q) => q.robotState),
                   shown.robot]) {
    x0 = Math.min(x0, p.x - reach);
    y0 = Math.min(y0, p.y - reach);
    x1 = Math.max(x1, p.x + reach);
    y1 = Math.max(y1, p.y + reach);
  }
  const w = x1 - x0, h = y1 - y0, unit = Math.max(w, h) / 700, font = Math.max(w, h) / 55;
  map.setAttribute('viewBox', `${x0} ${-y1} ${w} ${h}`);
  // World coordinates (y up) inside a flipped group; text is placed outside it, at (x, -y).
  const world = svg('g', {transform: 'scale(1,-1)'});
  const labels = svg('g', {class: 'labels'});
  // Inside a box the camera cannot see: hatched, so that the heat map's "not seen" colour under
  // it does not read as "likely here".
  const defs = svg('defs');
  const hatch = svg('pattern', {id: 'unknown-inside', patternUnits: 'userSpaceOnUse',
                                width: 6 * unit, height: 6 * unit,
                                patternTransform: 'rotate(45)'});
  hatch.append(svg('rect', {width: 6 * unit, height: 6 * unit, fill: '#ffffff',
                            'fill-opacity': 0.55}));
  hatch.append(svg('line', {x1: 0, y1: 0, x2: 0, y2: 6 * unit, stroke: COLORS.muted,
                            'stroke-width': 1.6 * unit}));
  defs.append(hatch);
  map.append(defs, world, labels);
  const label = (text, x, y, attrs = {}) => {
    const t = svg('text', {x, y: -y, 'font-size': font, 'stroke-width': font / 4,
                           class: 'map-label', ...attrs}, text);
    labels.append(t);
    return t;
  };
  const objectLabels = [];  // placed last, around their objects, clear of each other
  for (const r of belief.baseRegions || []) {
    world.append(svg('rect', {x: r.min[0], y: r.min[1], width: r.max[0] - r.min[0],
                              height: r.max[1] - r.min[1], fill: 'none', stroke: COLORS.region,
                              'stroke-width': unit, 'stroke-dasharray': `${4 * unit} ${3 * unit}`}));
  }
  for (const b of belief.furniture || []) {
    const k = boxCorners(b);
    world.append(svg('polygon', {points: points([k[0], k[1], k[3], k[2]]),
                                 fill: COLORS.furniture, stroke: COLORS.furnitureEdge,
                                 'stroke-width': unit}));
  }
  for (const ws of belief.grid.workspaces) {
    const deg = (ws.yaw || 0) * 180 / Math.PI;
    const g = svg('g', {transform: `translate(${ws.center[0]},${ws.center[1]}) rotate(${deg})`,
                        class: 'workspace', 'data-name': ws.name});
    g.append(svg('image', {href: heatImage(ws), x: -ws.length / 2, y: -ws.width / 2,
                           width: ws.length, height: ws.width, preserveAspectRatio: 'none',
                           class: 'heat'}));
    g.append(svg('rect', {x: -ws.length / 2, y: -ws.width / 2, width: ws.length,
                          height: ws.width, fill: 'none', stroke: COLORS.muted,
                          'stroke-width': unit}));
    world.append(g);
    const c = Math.cos(ws.yaw || 0), s = Math.sin(ws.yaw || 0);
    const lx = -ws.length / 2, ly = -ws.width / 2;
    label(`${ws.name} ${Math.round(100 * (ws.targetMass || 0))}%`,
          ws.center[0] + c * lx - s * ly, ws.center[1] + s * lx + c * ly - 1.6 * font,
          {class: 'ws-label map-label', 'font-weight': guess.workspace === ws.name ? 700 : 400});
  }
  // The robot's path and its past camera views up to the step shown (steps' observed states).
  const past = shown.path.filter((p) => p.robotState);
  for (const p of past) {
    if (p.view && p.view.length >= 3) {
      world.append(svg('polygon', {points: points(p.view), fill: 'none', stroke: COLORS.robot,
                                   'stroke-opacity': 0.35, 'stroke-width': unit, class: 'past-view',
                                   'data-step': p.step}));
    }
  }
  if (past.length) {
    const trail = past.map((p) => [p.robotState.x, p.robotState.y]);
    world.append(svg('polyline', {points: points(trail), fill: 'none', stroke: COLORS.robot,
                                  'stroke-width': 1.5 * unit, 'stroke-opacity': 0.8,
                                  class: 'path', 'data-points': trail.length}));
    for (const [x, y] of trail) {
      world.append(svg('circle', {cx: x, cy: y, r: 2.5 * unit, fill: COLORS.robot,
                                  class: 'path-point'}));
    }
  }
  robotShape(world, shown.robot, belief.robotRadius || 0.3, belief.robotFootprint, shown.frustum,
             COLORS.robot, false, unit);
  if (shown.live && belief.nextView) {
    robotShape(world, belief.nextView.configuration, belief.robotRadius || 0.3,
               belief.robotFootprint, belief.nextView.frustum, COLORS.next, true, unit);
  }
  const dot = Math.max(0.012, 3 * unit);
  for (const o of belief.objects) {
    const corners = boxCorners(o.box);
    const poly = [corners[0], corners[1], corners[3], corners[2]];
    const color = {DECLARED_TARGET: COLORS.target, DECLARED_OBSTACLE: COLORS.obstacle,
                   REMOVED: COLORS.removed}[o.status] || COLORS.object;
    const g = svg('g', {class: 'object', 'data-id': o.id, 'data-status': o.status});
    const p = sigmoid(meanOdds(o));
    g.append(svg('title', {}, `${o.id}: ${o.status.toLowerCase().replace('_', ' ')}, ` +
                 `P(target) ${p.toFixed(2)}; face log-odds ` +
                 o.faceLogOdds.map((v) => v.toFixed(1)).join(' ')));
    g.append(svg('polygon', {points: points(poly),
                             fill: o.status === 'REMOVED' ? 'none' : 'url(#unknown-inside)',
                             class: 'box', stroke: color,
                             'stroke-width': (o.status === 'REMOVED' ? 1 : 2.5) * unit,
                             ...(o.status === 'REMOVED' ?
                               {'stroke-dasharray': `${3 * unit} ${3 * unit}`} : {})}));
    if (o.status !== 'REMOVED') {
      for (let k = 0; k < 4; k++) {
        const [x, y] = corners[k];
        g.append(svg('circle', {cx: x, cy: y, r: dot * 1.6, class: 'face',
                                fill: rgb(probabilityColor(sigmoid(o.faceLogOdds[k]))),
                                stroke: COLORS.ink, 'stroke-width': unit * 0.8}));
        g.append(svg('circle', {cx: x, cy: y, r: dot * 0.8,
                                fill: rgb(probabilityColor(sigmoid(o.faceLogOdds[k + 4])))}));
      }
    }
    if (guess.object === o.id) {
      g.append(svg('circle', {cx: o.box.center[0], cy: o.box.center[1],
                              r: 0.6 * Math.hypot(o.box.size[0], o.box.size[1]) + 4 * dot,
                              fill: 'none', stroke: COLORS.target, 'stroke-width': 1.5 * unit,
                              'stroke-dasharray': `${2 * unit} ${2 * unit}`, class: 'guess-ring'}));
    }
    world.append(g);
    const top = Math.max(...poly.map((q) => q[1])), left = Math.min(...poly.map((q) => q[0]));
    const status = {DECLARED_TARGET: ' TARGET', DECLARED_OBSTACLE: ' obstacle',
                    REMOVED: ' removed'}[o.status] || '';
    objectLabels.push({
      el: label(`${o.id} P${p.toFixed(2)}${status}`, left, top + 2.2 * dot,
                {fill: color, class: 'map-label object-label', 'data-id': o.id}),
      poly: poly.map(([x, y]) => [x, -y])});
  }
  // Scale bar, bottom left: a round length near a seventh of the view.
  const target = Math.max(w, h) / 7;
  const length = [0.05, 0.1, 0.2, 0.25, 0.5, 1, 2, 5, 10, 20, 50].reduce(
      (a, b) => (Math.abs(Math.log(b / target)) < Math.abs(Math.log(a / target)) ? b : a));
  const sx = x0 + 0.04 * w, sy = y0 + 0.05 * h;
  const bar = svg('g', {id: 'scalebar', 'data-metres': length});
  bar.append(svg('rect', {x: sx - font * 0.4, y: -(sy + 2.2 * font), width: length + font * 0.8,
                          height: 2.8 * font, fill: '#fff', 'fill-opacity': 0.85}));
  bar.append(svg('line', {x1: sx, y1: -sy, x2: sx + length, y2: -sy, stroke: COLORS.ink,
                          'stroke-width': 2.5 * unit}));
  for (const x of [sx, sx + length]) {
    bar.append(svg('line', {x1: x, y1: -sy - font * 0.4, x2: x, y2: -sy + font * 0.4,
                            stroke: COLORS.ink, 'stroke-width': 2 * unit}));
  }
  bar.append(svg('text', {x: sx, y: -sy - 0.7 * font, 'font-size': font, class: 'scale-label'},
                 length >= 1 ? `${length} m` : `${Math.round(100 * length)} cm`));
  labels.append(bar);
  placeLabels(labels, objectLabels, [x0, -y1, w, h], font, unit);
}

// Moves each object's label to the first place near its object where it overlaps no label placed
// before it (the workspace labels and the scale bar included) and stays inside the map: beside
// the object first, then on rings around it, joined to it by a leader line. `view`: [x, y, w, h]
// of the map in SVG units (y down).
function placeLabels(group, items, view, font, unit) {
  const [vx, vy, vw, vh] = view;
  const pad = font * 0.15;
  const taken = [...group.querySelectorAll('.ws-label, #scalebar')].map((e) => e.getBBox());
  const overlap = (a, b) => Math.max(0, Math.min(a.x + a.width, b.x + b.width) - Math.max(a.x, b.x) + pad) *
      Math.max(0, Math.min(a.y + a.height, b.y + b.height) - Math.max(a.y, b.y) + pad);
  const outside = (b) => b.x < vx || b.y < vy || b.x + b.width > vx + vw || b.y + b.height > vy + vh;
  // Top to bottom, as a reader scans the map.
  items.sort((a, b) => a.poly[0][1] - b.poly[0][1]);
  for (const item of items) {
    const xs = item.poly.map((q) => q[0]), ys = item.poly.map((q) => q[1]);
    const left = Math.min(...xs), right = Math.max(...xs), top = Math.min(...ys),
        bottom = Math.max(...ys), cx = (left + right) / 2, cy = (top + bottom) / 2;
    const box0 = item.el.getBBox();
    const lw = box0.width, lh = box0.height;
    // Candidate top-left corners of the label's text box: beside the object, then rings.
    const beside = [[left, top - lh - pad], [left, bottom + pad], [right + pad, cy - lh / 2],
                    [left - lw - pad, cy - lh / 2], [right - lw, top - lh - pad],
                    [right - lw, bottom + pad]];
    const rings = [];
    for (const r of [2, 3, 4.5, 6.5, 9]) {
      for (let k = 0; k < 16; k++) {
        const a = (2 * Math.PI * k) / 16;
        rings.push([cx + r * font * Math.cos(a) - lw / 2, cy + r * font * Math.sin(a) - lh / 2]);
      }
    }
    let best = null;
    for (const [i, [x, y]] of [...beside, ...rings].entries()) {
      const b = {x, y, width: lw, height: lh};
      const cost = taken.reduce((sum, t) => sum + overlap(b, t), 0) + (outside(b) ? 1e9 : 0);
      if (!best || cost < best.cost) best = {x, y, cost, ring: i >= beside.length};
      if (cost === 0) break;
    }
    // Text is placed by its baseline: move it by the box's offset from (x, y).
    const dx = best.x - box0.x, dy = best.y - box0.y;
    item.el.setAttribute('x', Number(item.el.getAttribute('x')) + dx);
    item.el.setAttribute('y', Number(item.el.getAttribute('y')) + dy);
    const placed = {x: best.x, y: best.y, width: lw, height: lh};
    taken.push(placed);
    if (best.ring) {
      const tx = Math.min(Math.max(cx, placed.x), placed.x + lw);
      const ty = Math.min(Math.max(cy, placed.y), placed.y + lh);
      const leader = svg('line', {x1: cx, y1: cy, x2: tx, y2: ty, stroke: COLORS.muted,
                                  'stroke-width': unit, class: 'leader',
                                  'data-id': item.el.getAttribute('data-id')});
      group.insertBefore(leader, group.firstChild);
    }
  }
}

function renderColorbar() {
  const bar = $('colorbar');
  if (bar.childElementCount) return;
  const defs = svg('defs');
  const gradient = svg('linearGradient', {id: 'probability', x1: 0, x2: 1, y1: 0, y2: 0});
  for (const [p, r, g, b] of COLOR_STOPS) {
    gradient.append(svg('stop', {offset: p, 'stop-color': `rgb(${r},${g},${b})`}));
  }
  defs.append(gradient);
  bar.append(defs, svg('rect', {x: 5, y: 2, width: 250, height: 16, fill: 'url(#probability)',
                                stroke: COLORS.muted}));
  for (let t = 0; t <= 4; t++) {
    const x = 5 + 250 * t / 4;
    bar.append(svg('line', {x1: x, y1: 18, x2: x, y2: 23, stroke: COLORS.ink}));
    bar.append(svg('text', {x, y: 36, 'text-anchor': 'middle', 'font-size': 11,
                            class: 'tick'}, String(t / 4)));
  }
  const legend = $('legend');
  const item = (text, draw) => {
    const icon = svg('svg', {width: 28, height: 16, viewBox: '0 0 28 16'});
    draw(icon);
    const li = el('li');
    li.append(icon, el('span', {}, text));
    legend.append(li);
  };
  const box = (color, dashed) => (s) => s.append(svg('rect', {
    x: 5, y: 3, width: 18, height: 10, fill: 'none', stroke: color, 'stroke-width': 2,
    ...(dashed ? {'stroke-dasharray': '3 2'} : {})}));
  item('object: id and P(target) of its faces', box(COLORS.object));
  item('declared target', box(COLORS.target));
  item('declared obstacle', box(COLORS.obstacle));
  item('removed object', box(COLORS.removed, true));
  item('inside a box: not seen (hatched)', (s) => {
    s.append(svg('rect', {x: 5, y: 3, width: 18, height: 10, fill: '#eee', stroke: COLORS.object}));
    for (const x of [8, 13, 18]) {
      s.append(svg('line', {x1: x, y1: 13, x2: x + 5, y2: 3, stroke: COLORS.muted}));
    }
  });
  item("robot's path and past camera views", (s) => {
    s.append(svg('polyline', {points: '2,13 10,5 18,10 26,3', fill: 'none', stroke: COLORS.robot,
                              'stroke-width': 1.5}));
  });
  item('face odds at the corners (outer: lower, inner: upper)', (s) => {
    s.append(svg('circle', {cx: 14, cy: 8, r: 6, fill: rgb(probabilityColor(0.2)),
                            stroke: COLORS.ink}));
    s.append(svg('circle', {cx: 14, cy: 8, r: 3, fill: rgb(probabilityColor(0.8))}));
  });
  item('robot and its camera view', (s) => {
    s.append(svg('polygon', {points: '14,8 27,2 27,14', fill: COLORS.robot, 'fill-opacity': 0.2}));
    s.append(svg('circle', {cx: 9, cy: 8, r: 6, fill: 'none', stroke: COLORS.robot,
                            'stroke-width': 2}));
  });
  item('planned next view', (s) => s.append(svg('circle', {
    cx: 14, cy: 8, r: 6, fill: 'none', stroke: COLORS.next, 'stroke-width': 2,
    'stroke-dasharray': '3 2'})));
  item('furniture / base regions', (s) => {
    s.append(svg('rect', {x: 2, y: 3, width: 12, height: 10, fill: COLORS.furniture,
                          stroke: COLORS.furnitureEdge}));
    s.append(svg('rect', {x: 16, y: 3, width: 10, height: 10, fill: 'none', stroke: COLORS.region,
                          'stroke-dasharray': '2 2'}));
  });
}

// ---- side panels and the step table ----

function describeAction(a) {
  if (!a) return '';
  if (a.type === 'MOVE') {
    const c = a.configuration;
    return `MOVE x ${c.x.toFixed(2)} y ${c.y.toFixed(2)} yaw ${c.yaw.toFixed(2)} ` +
           `lift ${c.lift.toFixed(2)} pan ${c.pan.toFixed(2)} tilt ${c.tilt.toFixed(2)}`;
  }
  return `${a.type} ${a.objectId}`;
}

function describeOutcome(step) {
  const o = step.outcome;
  if (!o) return 'pending';
  if (o.done) return 'target removed';
  if (!o.succeeded) return 'failed';
  const seen = o.detections === 1 ? '1 object seen' : `${o.detections} objects seen`;
  const did = {MOVE: 'moved', DECLARE_TARGET: 'declared', DECLARE_OBSTACLE: 'declared',
               REMOVE: 'removed'}[step.action.type] || 'executed';
  return `${did}; ${seen}` +
         (o.newObjects ? ` (${o.newObjects} new)` : '') + (o.raw ? ', raw frame' : '');
}

function renderSteps(steps, current) {
  const body = $('steps').querySelector('tbody');
  body.replaceChildren();
  for (const s of steps) {
    const tr = el('tr', {'data-step': s.step});
    if (!s.outcome) tr.classList.add('pending');
    if (s.step === current) tr.classList.add('current');
    const cells = [s.step, describeAction(s.action), describeOutcome(s),
                   s.outcome ? fmt(s.outcome.reward, 0) : '', fmt(s.expectedValue, 1),
                   fmt(s.stats.simulations), fmt(s.stats.elapsedMs, 0), fmt(s.stats.cpuMs, 0),
                   fmt(s.stats.treeNodes)];
    for (const c of cells) tr.append(el('td', {}, String(c)));
    body.append(tr);
  }
}

function renderStats(session, steps) {
  const last = steps.length ? steps[steps.length - 1] : null;
  const rows = [
    ['steps', session.step],
    ['simulations (total)', fmt(session.totalSimulations)],
    ['planning time (total)', `${fmt(session.planningSecondsUsed, 1)} s`],
  ];
  if (last) {
    const s = last.stats;
    rows.push(['last plan: simulations', fmt(s.simulations)],
              ['last plan: simulations/s', fmt(s.simulations / Math.max(1e-3, s.elapsedMs / 1000))],
              ['last plan: tree nodes', fmt(s.treeNodes)],
              ['last plan: max depth', s.maxDepth],
              ['last plan: root actions', s.rootActions]);
    if (s.reusedVisits > 0) {
      rows.push(['last plan: reused', `${fmt(s.reusedVisits)} visits of the previous step's tree`]);
    }
    if (s.simulations === 0) {
      rows.push(['last plan: search', s.reusedVisits > 0 ?
        'no new simulations: the action comes from the reused tree' :
        'no simulations: the budget ran out before the search']);
    }
    if (s.candidates) {
      rows.push(['last plan: candidates kept', `${fmt(s.candidates.accepted)} of ` +
                 fmt(s.candidates.sampled)]);
    }
  }
  const dl = $('stats');
  dl.replaceChildren();
  for (const [k, v] of rows) dl.append(el('dt', {}, k), el('dd', {}, String(v)));
}

function renderObjects(belief) {
  const body = $('objects').querySelector('tbody');
  body.replaceChildren();
  for (const o of belief.objects) {
    const tr = el('tr', {'data-id': o.id});
    const faces = el('td');
    for (const v of o.faceLogOdds) {
      const swatch = el('span', {class: 'swatch', title: v.toFixed(2)});
      swatch.style.background = rgb(probabilityColor(sigmoid(v)));
      faces.append(swatch);
    }
    tr.append(el('td', {}, o.id), el('td', {}, o.status.toLowerCase().replace('_', ' ')),
              el('td', {class: 'num'}, sigmoid(meanOdds(o)).toFixed(2)), faces);
    body.append(tr);
  }
}

// What the timeline shows: the latest state (live), or step k of the observed steps: the robot
// where it stood after step k, the path and views up to it, and the belief this page saw right
// after it (or the latest, said so, for a step the page did not watch).
function shownStep(session, belief, steps) {
  const observed = steps.filter((s) => s.outcome);
  const last = observed.length ? observed[observed.length - 1].step : 0;
  const k = state.shown === null ? last : Math.min(state.shown, last);
  const live = state.shown === null || k === last;
  const upto = observed.filter((s) => s.step <= k);
  const at = upto.length ? upto[upto.length - 1] : null;
  const seen = state.beliefs.get(k);
  const shown = {
    step: k, last, live, path: upto.map((s) => ({step: s.step, robotState: s.outcome.robotState,
                                                 view: s.outcome.view})),
    robot: belief.robot, frustum: belief.camera.frustum, belief: live ? belief : seen || belief,
    beliefOfStep: live || !!seen,
  };
  if (!live && at && at.outcome.robotState) {
    shown.robot = at.outcome.robotState;
    shown.frustum = at.outcome.view || [];
  }
  return shown;
}

function renderTimeline(shown) {
  const slider = $('timeline');
  slider.max = String(shown.last);
  slider.value = String(shown.step);
  $('step-back').disabled = shown.step <= 0;
  $('step-forward').disabled = shown.live;
  $('live').classList.toggle('on', state.shown === null);
  $('timeline-label').textContent = shown.live ?
      `step ${shown.step} of ${shown.last}, live` :
      `step ${shown.step} of ${shown.last}` + (shown.beliefOfStep ? '' :
        ' (the belief as it is now: this page did not watch that step)');
}

function show(step) {
  state.shown = step;
  if (state.latest) renderDetail(state.latest.session, state.latest.belief, state.latest.steps);
}

function renderDetail(session, belief, steps) {
  state.latest = {session, belief, steps};
  $('detail').classList.remove('hidden');
  $('session-title').textContent = `session ${session.id} · step ${session.step} · ` +
      session.state.toLowerCase().replace('_', ' ');
  const meta = [describePlanner(session.planner), `${session.planner.particles} particles`];
  if (session.displayName) meta.unshift(session.displayName);
  if (session.target && session.target.description) meta.push(`target: ${session.target.description}`);
  meta.push(`updated ${new Date(session.updateTime).toLocaleTimeString()}`);
  $('session-meta').textContent = meta.join(' · ');
  const shown = shownStep(session, belief, steps);
  const guess = bestGuess(shown.belief, shown.live ? session : null, steps);
  $('best-guess').textContent = guess.text;
  const pending = session.pendingAction;
  $('next-action').textContent = pending ? `next: ${describeAction(pending.action)}` :
      session.state === 'DONE' ? 'done: the target was removed' : '';
  renderColorbar();
  renderTimeline(shown);
  renderMap(shown.belief, guess, shown);
  renderStats(session, steps);
  renderObjects(shown.belief);
  renderSteps(steps, shown.live ? null : shown.step);
}

// ---- the refresh loop ----

async function refresh() {
  try {
    const health = await api('/healthz');
    $('health').textContent = health.status.toLowerCase();
    $('health').className = 'pill ok';
  } catch (e) {
    $('health').textContent = 'unreachable';
    $('health').className = 'pill bad';
    return;
  }
  try {
    const sessions = await listSessions();
    state.needsKey = false;
    $('auth').classList.toggle('hidden', !state.apiKey);
    $('auth-message').textContent = '';
    if (!state.selected && sessions.length) {
      // The most recently updated session.
      state.selected = sessions.reduce((a, b) => (a.updateTime >= b.updateTime ? a : b)).id;
    }
    renderSessions(sessions);
    const current = sessions.find((s) => s.id === state.selected);
    if (!current) {
      $('detail').classList.add('hidden');
      return;
    }
    const seen = current.updateTime + current.state + current.step;
    if (seen !== state.lastSeen) {
      const id = encodeURIComponent(current.id);
      const [session, belief, steps] = await Promise.all([
        api(`/v1/sessions/${id}`), api(`/v1/sessions/${id}/belief`),
        api(`/v1/sessions/${id}/steps`)]);
      const observed = steps.steps.filter((s) => s.outcome).length;
      if (!state.beliefs.has(observed)) state.beliefs.set(observed, belief);
      renderDetail(session, belief, steps.steps);
      state.lastSeen = seen;
      document.body.dataset.step = String(session.step);
      document.body.dataset.sessionState = session.state;
    }
    $('updated').textContent = `refreshed ${new Date().toLocaleTimeString()}`;
  } catch (e) {
    if (state.needsKey) {
      $('auth').classList.remove('hidden');
      $('auth-message').textContent = state.apiKey ? 'wrong API key' : 'this server needs an API key';
    } else {
      $('updated').textContent = `error: ${e.message}`;
    }
  }
}

function start() {
  $('auth').addEventListener('submit', (event) => {
    event.preventDefault();
    state.apiKey = $('api-key').value.trim();
    sessionStorage.setItem('npfkct.apiKey', state.apiKey);
    state.lastSeen = '';
    refresh();
  });
  $('timeline').addEventListener('input', () => {
    const k = Number($('timeline').value);
    show(state.latest && k >= Number($('timeline').max) ? null : k);
  });
  $('step-back').addEventListener('click', () => {
    const k = Number($('timeline').value);
    if (k > 0) show(k - 1);
  });
  $('step-forward').addEventListener('click', () => {
    const k = Number($('timeline').value) + 1;
    show(k >= Number($('timeline').max) ? null : k);
  });
  $('live').addEventListener('click', () => show(null));
  window.addEventListener('resize', () => { if (state.latest) show(state.shown); });
  window.addEventListener('hashchange', () => {
    state.selected = selectedFromHash();
    state.lastSeen = '';
    state.shown = null;
    state.beliefs = new Map();
    refresh();
  });
  refresh();
  setInterval(refresh, REFRESH_MS);
}

document.addEventListener('DOMContentLoaded', start);
