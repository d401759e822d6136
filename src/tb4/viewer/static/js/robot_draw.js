// Drawing what moves: the robot, AMCL's particles, the lidar scan and the waypoints of the current task.

import { ctx, worldToScreen } from "./canvas.js";
import { COLORS, S, view } from "./state.js";

export function drawParticles(flat) {
  ctx.fillStyle = COLORS.particles;
  for (let i = 0; i < flat.length; i += 2) {
    const [px, py] = worldToScreen(flat[i], flat[i + 1]);
    ctx.fillRect(px - 1, py - 1, 2, 2);
  }
}

export function drawScan(flat) {
  ctx.fillStyle = COLORS.scan;
  const d = Math.max(3, Math.min(6, 0.06 * view.scale));
  for (let i = 0; i < flat.length; i += 2) {
    const [px, py] = worldToScreen(flat[i], flat[i + 1]);
    ctx.fillRect(px - d / 2, py - d / 2, d, d);
  }
}

export function drawWaypoints(waypoints) {
  waypoints.forEach((w, i) => {
    const [px, py] = worldToScreen(w.x, w.y);
    ctx.beginPath();
    ctx.arc(px, py, 8, 0, 2 * Math.PI);
    ctx.fillStyle = w.status === 1 ? "rgba(38, 194, 129, 0.9)" : COLORS.waypoint;
    ctx.fill();
    ctx.fillStyle = "#1b1b1b";
    ctx.font = "600 10px system-ui, sans-serif";
    ctx.fillText(String(i + 1), px - 3, py + 4);
  });
}

function rgba(hex, alpha) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255}, ${(n >> 8) & 255}, ${n & 255}, ${alpha})`;
}

/**
 * A robot at its pose; returns where it is on screen. `color`: its fleet colour (none: the one-robot look);
 * `label`: its name, drawn beside it; `picked`: the robot the tools command, ringed when there are several.
 */
export function drawRobot(r, { color = null, label = null, picked = false } = {}) {
  const [px, py] = worldToScreen(r.x, r.y);
  const rad = Math.max(5, r.radius * view.scale);
  ctx.beginPath();
  ctx.arc(px, py, rad + (picked && color ? 4 : 2), 0, 2 * Math.PI); // a light halo keeps it visible on any background
  ctx.fillStyle = "rgba(255, 255, 255, 0.85)";
  ctx.fill();
  if (picked && color) {
    ctx.lineWidth = 2;
    ctx.strokeStyle = "#0b1320";
    ctx.stroke();
  }
  ctx.beginPath();
  ctx.arc(px, py, rad, 0, 2 * Math.PI);
  if (color) ctx.fillStyle = rgba(color, r.localized ? 0.55 : 0.25);
  else ctx.fillStyle = r.localized ? "rgba(63, 167, 255, 0.55)" : "rgba(160, 160, 170, 0.55)";
  ctx.fill();
  ctx.lineWidth = 2;
  ctx.strokeStyle = r.localized ? (color ? "#0b1320" : COLORS.robotEdge) : "#555";
  ctx.stroke();
  ctx.beginPath();
  ctx.moveTo(px, py);
  ctx.lineTo(px + Math.cos(r.yaw) * rad * 1.6, py - Math.sin(r.yaw) * rad * 1.6);
  ctx.lineWidth = 3;
  ctx.strokeStyle = "#0b1320";
  ctx.stroke();
  ctx.beginPath();
  ctx.arc(px, py, color ? Math.max(3.5, rad * 0.35) : Math.max(2.5, rad * 0.25), 0, 2 * Math.PI);
  ctx.fillStyle = color || COLORS.robot;
  ctx.fill();
  if (label) {
    ctx.font = `${picked ? 700 : 600} 12px system-ui, sans-serif`;
    const w = ctx.measureText(label).width;
    ctx.fillStyle = "rgba(20, 26, 36, 0.8)";
    ctx.fillRect(px + rad + 3, py - rad - 14, w + 6, 16);
    ctx.fillStyle = color || "#e6ebf2";
    ctx.fillText(label, px + rad + 6, py - rad - 2);
  }
  return { x: px, y: py, radius: rad, worldX: r.x, worldY: r.y }; // what was drawn, and where
}
