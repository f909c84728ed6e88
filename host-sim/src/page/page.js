// The live page: polls /state.json and draws it. The map's cells are drawn in the PNG
// map's colours (host-sim/src/picture.rs), a whole number of pixels each, at the place
// the state's `layout` gives, so that a screenshot can be compared cell for cell.
"use strict";

const COLOURS = {
  unknown: "#efe6d2", // the mat
  free: "#9ecae1",
  occupied: "#000000",
  edge: "#b8ab8c",
  wall: "#6b8e6b",
  truth: "#1a9850",
  estimate: "#f06a14",
  tag: "#333333",
};
const CELL_COLOURS = { "1": COLOURS.free, "2": COLOURS.occupied };
const POLL_MS = 250;

const mapCanvas = document.getElementById("map");
const overlay = document.getElementById("overlay");
const showOverlay = document.getElementById("show-overlay");
let drawnMap = null;
let drawnVersion = -1;

showOverlay.addEventListener("change", () => {
  overlay.style.display = showOverlay.checked ? "" : "none";
});

function place(canvas, layout) {
  const w = layout.columns * layout.cell_px;
  const h = layout.rows * layout.cell_px;
  canvas.style.left = layout.left_px + "px";
  canvas.style.top = layout.top_px + "px";
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
    return true;
  }
  return false;
}

function drawMap(s) {
  const l = s.layout;
  const resized = place(mapCanvas, l);
  if (!resized && s.map === drawnMap) return;
  const g = mapCanvas.getContext("2d");
  const cp = l.cell_px;
  g.fillStyle = COLOURS.unknown;
  g.fillRect(0, 0, mapCanvas.width, mapCanvas.height);
  for (let row = 0; row < l.rows; row++) {
    const y = (l.rows - 1 - row) * cp;
    const start = row * l.columns;
    let col = 0;
    while (col < l.columns) {
      const c = s.map[start + col];
      let run = 1;
      while (col + run < l.columns && s.map[start + col + run] === c) run++;
      const colour = CELL_COLOURS[c];
      if (colour) {
        g.fillStyle = colour;
        g.fillRect(col * cp, y, run * cp, cp);
      }
      col += run;
    }
  }
  drawnMap = s.map;
}

function drawOverlay(s) {
  const l = s.layout;
  const grid = s.grid;
  place(overlay, l);
  const g = overlay.getContext("2d");
  g.clearRect(0, 0, overlay.width, overlay.height);
  const px = (p) => [
    ((p[0] - grid.origin_x_mm) / grid.cell_mm) * l.cell_px,
    l.rows * l.cell_px - ((p[1] - grid.origin_y_mm) / grid.cell_mm) * l.cell_px,
  ];
  g.strokeStyle = COLOURS.edge;
  g.lineWidth = 1;
  g.strokeRect(0.5, 0.5, overlay.width - 1, overlay.height - 1);
  g.strokeStyle = COLOURS.wall;
  g.lineWidth = 2;
  for (const [a, b] of s.walls) {
    g.beginPath();
    g.moveTo(...px(a));
    g.lineTo(...px(b));
    g.stroke();
  }
  for (const [points, colour] of [[s.truth, COLOURS.truth], [s.estimate, COLOURS.estimate]]) {
    if (points.length < 1) continue;
    g.strokeStyle = colour;
    g.lineWidth = 2;
    g.beginPath();
    points.forEach((p, i) => (i ? g.lineTo : g.moveTo).apply(g, px([p.x_mm, p.y_mm])));
    g.stroke();
  }
  for (const [pose, colour] of [[s.true_pose, COLOURS.truth], [s.pose, COLOURS.estimate]]) {
    if (!pose) continue;
    const [x, y] = px([pose.x_mm, pose.y_mm]);
    const h = (pose.heading_deg * Math.PI) / 180;
    g.fillStyle = colour;
    g.beginPath();
    g.arc(x, y, 4, 0, 2 * Math.PI);
    g.fill();
    g.strokeStyle = colour;
    g.beginPath();
    g.moveTo(x, y);
    g.lineTo(x + 12 * Math.sin(h), y - 12 * Math.cos(h));
    g.stroke();
  }
  g.font = "14px sans-serif";
  for (const t of s.tags) {
    const [x, y] = px([t.x_mm, t.y_mm]);
    g.fillStyle = "#fff";
    g.fillRect(x - 6, y - 6, 12, 12);
    g.strokeStyle = COLOURS.tag;
    g.lineWidth = 2;
    g.strokeRect(x - 6, y - 6, 12, 12);
    g.fillStyle = COLOURS.tag;
    g.fillRect(x - 2, y - 2, 4, 4);
    const label = String(t.id);
    g.fillStyle = "rgba(255, 255, 255, 0.85)";
    g.fillRect(x + 7, y - 24, 6 + 9 * label.length, 16);
    g.fillStyle = COLOURS.tag;
    g.fillText(label, x + 10, y - 11);
  }
}

const fmt = (v, digits) => (v === null || v === undefined ? "–" : Number(v).toFixed(digits));

function progressLine(f) {
  if (f.tick === null) return "connected: no tick yet";
  const st = f.stale;
  return (
    `tick ${f.tick} · ${fmt(f.time_s, 1)} s · fixes ${f.fixes_taken}` +
    (f.fixes_rejected ? ` (rejected ${f.fixes_rejected})` : "") +
    (f.filter ? ` · tag sightings used ${f.filter.belief.tags.used}` : "") +
    ` · stale inputs: flow ${st.flow}, gyro ${st.gyro}, depth ${st.depth}` +
    ` · known ${fmt(f.known_pct, 0)} %`
  );
}

function figureRows(s) {
  const f = s.figures;
  const rows = [];
  const add = (name, value) => rows.push([name, value]);
  if (s.pose) add("pose", `${fmt(s.pose.x_mm, 0)}, ${fmt(s.pose.y_mm, 0)} mm, ${fmt(s.pose.heading_deg, 1)}°`);
  if (s.true_pose) add("true pose", `${fmt(s.true_pose.x_mm, 0)}, ${fmt(s.true_pose.y_mm, 0)} mm, ${fmt(s.true_pose.heading_deg, 1)}°`);
  if (f.error_cm !== null) add("error", `${fmt(f.error_cm, 2)} cm`);
  if (f.filter) {
    const b = f.filter.belief;
    const refused = Object.values(b.tags.refused).reduce((a, n) => a + n, 0);
    add("3σ bound", `${fmt(f.filter.bound_3sigma_cm, 2)} cm, ${fmt(f.filter.bound_3sigma_heading_deg, 2)}°`);
    add("gyro scale, bias", `${fmt(b.gyro_scale_ppm, 0)} ppm, ${fmt(b.gyro_bias_mdps, 0)} mdps`);
    add("flow scale", `${fmt(b.flow_scale_ppm, 0)} ppm`);
    add("tag sightings", `${b.tags.used} used, ${refused} refused`);
  }
  add("cells", `${f.free} free, ${f.occupied} occupied`);
  add("beams mapped", f.beams_mapped);
  if (s.grid) add("grid", `${s.grid.width} × ${s.grid.height} of ${s.grid.cell_mm} mm`);
  if (f.health) {
    for (const [name, n] of Object.entries(f.health)) {
      if (n && name !== "watchdog_feeds") add(name.replaceAll("_", " "), n);
    }
  }
  return rows;
}

function drawFigures(s) {
  const f = s.figures;
  document.getElementById("progress").textContent = progressLine(f);
  document.getElementById("source").textContent = f.firmware
    ? `firmware ${f.firmware} · ${f.localiser}`
    : "";
  const table = document.getElementById("figures");
  table.replaceChildren(
    ...figureRows(s).map(([name, value]) => {
      const tr = document.createElement("tr");
      const th = document.createElement("th");
      const td = document.createElement("td");
      th.textContent = name;
      td.textContent = String(value);
      tr.append(th, td);
      return tr;
    }),
  );
  const link = f.link;
  const refused = link.hellos_refused + link.map_rows_refused;
  document.getElementById("link").textContent =
    `${link.messages} messages` +
    (refused ? `, ${refused} refused` : "") +
    (link.restarts ? `, ${link.restarts} restarts` : "");
}

function draw(s) {
  drawFigures(s);
  if (s.layout && s.grid) {
    drawMap(s);
    drawOverlay(s);
  }
  document.body.dataset.version = s.version;
  document.body.dataset.tick = s.figures.tick === null ? "" : s.figures.tick;
}

async function poll() {
  const link = document.getElementById("link");
  try {
    const response = await fetch("/state.json", { cache: "no-store" });
    if (!response.ok) throw new Error(`HTTP ${response.status}`);
    const s = await response.json();
    if (s.version !== drawnVersion) {
      draw(s);
      drawnVersion = s.version;
    }
    link.classList.remove("lost");
  } catch (e) {
    link.classList.add("lost");
    link.textContent = `lost the connection (${e.message}): retrying`;
  }
  setTimeout(poll, POLL_MS);
}

poll();
