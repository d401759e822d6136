// Drawing the map side of the picture: grid layers (map and costmaps), lines (plan, trail), the world's docks,
// named places and route graph, pose arrows, labels and the scale bar.

import { ctx, size, worldToScreen } from "./canvas.js";
import { COLORS, S, view } from "./state.js";

export function drawLayer(layer, alpha) {
  if (!layer || !layer.image) return;
  const dpr = window.devicePixelRatio || 1;
  const [sx, sy] = worldToScreen(layer.origin[0], layer.origin[1]);
  ctx.save();
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.translate(sx, sy);
  ctx.rotate(-layer.origin[2]); // screen y points down: a counter-clockwise yaw turns the other way
  ctx.scale(layer.resolution * view.scale, layer.resolution * view.scale);
  ctx.globalAlpha = alpha;
  ctx.imageSmoothingEnabled = view.scale * layer.resolution < 1.5; // crisp cells when zoomed in
  ctx.drawImage(layer.image, 0, -layer.height); // the image's top row is the grid's highest row
  ctx.restore();
}

export function polyline(flat, color, width, dash) {
  if (flat.length < 4) return;
  ctx.beginPath();
  for (let i = 0; i < flat.length; i += 2) {
    const [px, py] = worldToScreen(flat[i], flat[i + 1]);
    if (i === 0) ctx.moveTo(px, py);
    else ctx.lineTo(px, py);
  }
  ctx.strokeStyle = color;
  ctx.lineWidth = width;
  ctx.lineJoin = "round";
  ctx.setLineDash(dash || []);
  ctx.stroke();
  ctx.setLineDash([]);
}

export function arrow(x, y, yaw, color, length) {
  const [px, py] = worldToScreen(x, y);
  const len = length || Math.max(22, 0.6 * view.scale);
  const ex = px + Math.cos(yaw) * len;
  const ey = py - Math.sin(yaw) * len;
  ctx.strokeStyle = color;
  ctx.fillStyle = color;
  ctx.lineWidth = 3;
  ctx.beginPath();
  ctx.moveTo(px, py);
  ctx.lineTo(ex, ey);
  ctx.stroke();
  const head = 9;
  ctx.beginPath();
  ctx.moveTo(ex + Math.cos(yaw) * 4, ey - Math.sin(yaw) * 4);
  ctx.lineTo(ex - Math.cos(yaw - 0.5) * head, ey + Math.sin(yaw - 0.5) * head);
  ctx.lineTo(ex - Math.cos(yaw + 0.5) * head, ey + Math.sin(yaw + 0.5) * head);
  ctx.closePath();
  ctx.fill();
  ctx.beginPath();
  ctx.arc(px, py, 4, 0, 2 * Math.PI);
  ctx.fill();
}

function label(text, px, py, color) {
  ctx.font = "600 12px system-ui, sans-serif";
  const w = ctx.measureText(text).width;
  ctx.fillStyle = "rgba(20, 26, 36, 0.8)";
  ctx.fillRect(px - 3, py - 12, w + 6, 16);
  ctx.fillStyle = color;
  ctx.fillText(text, px, py);
}

function drawRouteGraph(graph) {
  // Nav2 route graph: thin teal edges, small nodes, ids once zoomed in far enough to read them.
  ctx.save();
  ctx.strokeStyle = "rgba(38, 166, 154, 0.75)";
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  for (const [x0, y0, x1, y1] of graph.edges || []) {
    const [ax, ay] = worldToScreen(x0, y0);
    const [bx, by] = worldToScreen(x1, y1);
    ctx.moveTo(ax, ay);
    ctx.lineTo(bx, by);
  }
  ctx.stroke();
  ctx.fillStyle = "#26a69a";
  ctx.font = "10px system-ui, sans-serif";
  for (const [id, x, y] of graph.nodes || []) {
    const [px, py] = worldToScreen(x, y);
    ctx.beginPath();
    ctx.arc(px, py, 3, 0, 2 * Math.PI);
    ctx.fill();
    if (view.scale > 25) ctx.fillText(String(id), px + 4, py - 4);
  }
  ctx.restore();
}

/** One dock station, labelled; returns what was drawn and where (S.docksScreen, read by the tests). */
function drawDock(d) {
  // The station sits just ahead of the docked robot's pose.
  const sx = d.x + Math.cos(d.yaw) * 0.25;
  const sy = d.y + Math.sin(d.yaw) * 0.25;
  const [px, py] = worldToScreen(sx, sy);
  const s = Math.max(8, 0.3 * view.scale);
  ctx.save();
  ctx.translate(px, py);
  ctx.rotate(-d.yaw);
  ctx.fillStyle = COLORS.dock;
  ctx.strokeStyle = "#3b3000";
  ctx.lineWidth = 1.5;
  ctx.fillRect(-s * 0.3, -s / 2, s * 0.6, s);
  ctx.strokeRect(-s * 0.3, -s / 2, s * 0.6, s);
  ctx.restore();
  const text = d.label || "dock";
  label(text, px + s * 0.6, py + 4, COLORS.dock);
  return { label: text, x: px, y: py, width: s * 0.6, length: s, worldX: d.x, worldY: d.y, yaw: d.yaw };
}

/** The world's docks, named places and route graph; returns the docks drawn (see drawDock). */
export function drawPlaces() {
  const world = S.world;
  if (!world) return []; // a real robot: no world, only the map
  if (world.route_graph) drawRouteGraph(world.route_graph);
  const docks = world.docks || (world.dock ? [world.dock] : []); // a server that sends only its first dock
  const drawn = docks.map(drawDock);
  for (const p of world.destinations || []) {
    const [px, py] = worldToScreen(p.x, p.y);
    ctx.fillStyle = COLORS.place;
    ctx.strokeStyle = "#1d1550";
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.moveTo(px, py - 7);
    ctx.lineTo(px + 6, py);
    ctx.lineTo(px, py + 7);
    ctx.lineTo(px - 6, py);
    ctx.closePath();
    ctx.fill();
    ctx.stroke();
    label(p.name, px + 9, py + 4, "#cfc9ff");
  }
  return drawn;
}

export function drawScaleBar() {
  const { w, h } = size();
  const most = 150 / view.scale; // a round length in metres that fits in 150 px
  const nice = [500, 200, 100, 50, 20, 10, 5, 2, 1, 0.5, 0.2, 0.1].find((m) => m <= most) || 0.1;
  const len = nice * view.scale;
  const x = w - len - 16;
  const y = h - 40;
  ctx.fillStyle = "rgba(20, 26, 36, 0.78)";
  ctx.fillRect(x - 8, y - 16, len + 16, 26);
  ctx.strokeStyle = "#e6ebf2";
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.moveTo(x, y - 4);
  ctx.lineTo(x, y + 2);
  ctx.lineTo(x + len, y + 2);
  ctx.lineTo(x + len, y - 4);
  ctx.stroke();
  ctx.fillStyle = "#e6ebf2";
  ctx.font = "12px system-ui, sans-serif";
  ctx.fillText(`${nice} m`, x + len / 2 - 10, y - 4);
}
