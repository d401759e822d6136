// One frame: every layer in order, at most once per animation frame and only after something changed.

import { canvas, ctx } from "./canvas.js";
import { arrow, drawLayer, drawPlaces, drawScaleBar, polyline } from "./map_draw.js";
import { drawParticles, drawRobot, drawScan, drawWaypoints } from "./robot_draw.js";
import { COLORS, pointer, S, show, takeRedraw } from "./state.js";

/** The fleet robots the tools do not command: their trails and plans (under everything else), in their colours. */
function drawOtherPaths(others) {
  for (const r of others) {
    if (show.trail) polyline(r.trail, r.color, 2);
    if (show.plan) polyline(r.plan, r.color, 2.5, [8, 5]);
  }
}

/** ... and their goals and bodies, labelled with their names (S.fleetScreen: where to click to pick one). */
function drawOtherRobots(others) {
  for (const r of others) if (r.goal) arrow(r.goal.x, r.goal.y, r.goal.yaw, r.color);
  for (const r of others) {
    if (!r.robot) continue;
    const screen = drawRobot(r.robot, { color: r.color, label: r.namespace });
    S.fleetScreen.push({ namespace: r.namespace, ...screen });
  }
}

function draw() {
  S.frames += 1;
  const dpr = window.devicePixelRatio || 1;
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.fillStyle = COLORS.background;
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  drawLayer(S.layers.map, 1);
  if (show.global_costmap) drawLayer(S.layers.global_costmap, 0.6);
  if (show.local_costmap) drawLayer(S.layers.local_costmap, 0.9);
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  S.fleetScreen = [];
  const color = S.color; // the commanded robot's fleet colour, or null: the one-robot colours
  const others = S.fleet.filter((r) => !r.picked);
  drawOtherPaths(others);
  if (show.trail) polyline(S.trail, color || COLORS.trail, 2.5);
  if (show.plan) polyline(S.plan, color || COLORS.plan, 3);
  S.docksScreen = show.places ? drawPlaces() : [];
  drawOtherRobots(others);
  if (S.particles && S.particles.length) drawParticles(S.particles);
  if (show.scan && S.scan.length) drawScan(S.scan);
  drawWaypoints(S.waypoints);
  if (S.goal) arrow(S.goal.x, S.goal.y, S.goal.yaw, color || COLORS.goal);
  if (S.robot) {
    const label = color ? S.namespace : null;
    S.robotScreen = drawRobot(S.robot, { color, label, picked: true });
    if (color) S.fleetScreen.push({ namespace: S.namespace, ...S.robotScreen });
  } else S.robotScreen = null;
  drawScaleBar();
  const drag = pointer.drag;
  if (drag && drag.tool !== "pan") arrow(drag.x, drag.y, drag.yaw, drag.tool === "pose" ? COLORS.pose : COLORS.goal, 40);
}

export function startRendering() {
  function frame() {
    if (takeRedraw()) draw();
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
}
