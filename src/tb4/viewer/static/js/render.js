// One frame: every layer in order, at most once per animation frame and only after something changed.

import { canvas, ctx } from "./canvas.js";
import { arrow, drawLayer, drawPlaces, drawScaleBar, polyline } from "./map_draw.js";
import { drawParticles, drawRobot, drawScan, drawWaypoints } from "./robot_draw.js";
import { COLORS, pointer, S, show, takeRedraw } from "./state.js";

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
  if (show.trail) polyline(S.trail, COLORS.trail, 2.5);
  if (show.plan) polyline(S.plan, COLORS.plan, 3);
  if (show.places) drawPlaces();
  if (S.particles && S.particles.length) drawParticles(S.particles);
  if (show.scan && S.scan.length) drawScan(S.scan);
  drawWaypoints(S.waypoints);
  if (S.goal) arrow(S.goal.x, S.goal.y, S.goal.yaw, COLORS.goal);
  if (S.robot) drawRobot(S.robot);
  else S.robotScreen = null;
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
