// The page's tools: Pan (drag, wheel zoom), 2D Pose Estimate and Nav2 Goal (click-drag a pose, used once like
// RViz's), Cancel, the Create 3 buttons, the layer switches, follow, fit and the robot namespace picker. In a
// fleet, clicking a robot (on the map with Pan, or in the legend) makes it the one the tools command.

import { $, canvas, fitMap, screenToWorld } from "./canvas.js";
import { send, sendLayers } from "./connection.js";
import { onPick } from "./panels.js";
import { pointer, redraw, S, show, view } from "./state.js";

function setTool(tool) {
  S.tool = tool;
  for (const b of document.querySelectorAll("[data-tool]")) b.classList.toggle("active", b.dataset.tool === tool);
  canvas.className = tool === "pan" ? "" : tool;
}

/** Command `namespace` with the tools from now on. */
function pick(namespace) {
  if (namespace !== S.namespace) send({ type: "namespace", namespace });
}

/** The fleet robot drawn under screen point (px, py), if any (the nearest one when bodies overlap). */
function robotAt(px, py) {
  let best = null;
  for (const r of S.fleetScreen) {
    const d = Math.hypot(px - r.x, py - r.y);
    if (d <= r.radius + 4 && (!best || d < best.d)) best = { namespace: r.namespace, d };
  }
  return best && best.namespace;
}

function eventPoint(e) {
  const r = canvas.getBoundingClientRect();
  return [e.clientX - r.left, e.clientY - r.top];
}

function bindPanel() {
  for (const b of document.querySelectorAll("[data-tool]")) b.addEventListener("click", () => setTool(b.dataset.tool));
  $("cancel").addEventListener("click", () => send({ type: "cancel" }));
  document
    .querySelectorAll(".c3-button")
    .forEach((b) => b.addEventListener("click", () => send({ type: "press", button: b.dataset.button })));
  $("fit").addEventListener("click", fitMap);
  $("follow").addEventListener("change", (e) => {
    view.follow = e.target.checked;
    redraw();
  });
  for (const box of document.querySelectorAll("[data-layer]")) {
    box.addEventListener("change", () => {
      show[box.dataset.layer] = box.checked;
      if (box.dataset.layer.endsWith("costmap")) sendLayers();
      redraw();
    });
  }
  $("namespace").addEventListener("change", (e) => send({ type: "namespace", namespace: e.target.value }));
  onPick(pick);
}

function bindMouse() {
  canvas.addEventListener("mousedown", (e) => {
    const [px, py] = eventPoint(e);
    const tool = e.button === 0 ? S.tool : "pan"; // middle/right button always pans
    const [x, y] = screenToWorld(px, py);
    pointer.drag = { tool, px, py, x, y, yaw: 0, cx: view.cx, cy: view.cy };
    if (tool === "pan") canvas.classList.add("dragging");
    canvas.focus();
    e.preventDefault();
  });
  window.addEventListener("mousemove", (e) => {
    const [px, py] = eventPoint(e);
    const [wx, wy] = screenToWorld(px, py);
    $("cursor").textContent = `${wx.toFixed(2)}, ${wy.toFixed(2)}`;
    const drag = pointer.drag;
    if (!drag) return;
    if (drag.tool === "pan") {
      view.cx = drag.cx - (px - drag.px) / view.scale;
      view.cy = drag.cy + (py - drag.py) / view.scale;
      view.follow = false;
      $("follow").checked = false;
    } else if (Math.hypot(px - drag.px, py - drag.py) > 3) {
      drag.yaw = Math.atan2(-(py - drag.py), px - drag.px); // screen y grows downwards
    }
    redraw();
  });
  window.addEventListener("mouseup", (e) => {
    const d = pointer.drag;
    if (!d) return;
    pointer.drag = null;
    canvas.classList.remove("dragging");
    const [px, py] = eventPoint(e);
    if (d.tool === "pan" && e.button === 0 && Math.hypot(px - d.px, py - d.py) <= 3) {
      const namespace = robotAt(px, py); // a click (not a drag) on a fleet robot picks it
      if (namespace) pick(namespace);
    }
    if (d.tool === "pose" || d.tool === "goal") {
      send({ type: d.tool === "pose" ? "initial_pose" : "goal", x: d.x, y: d.y, yaw: d.yaw });
      setTool("pan"); // like RViz: a pose tool is used once
    }
    redraw();
  });
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener(
    "wheel",
    (e) => {
      const [px, py] = eventPoint(e);
      const [wx, wy] = screenToWorld(px, py);
      const factor = Math.exp(-e.deltaY * 0.0015);
      view.scale = Math.min(400, Math.max(0.5, view.scale * factor));
      const [nx, ny] = screenToWorld(px, py); // keep the point under the cursor in place
      view.cx += wx - nx;
      view.cy += wy - ny;
      redraw();
      e.preventDefault();
    },
    { passive: false },
  );
}

function bindKeys() {
  window.addEventListener("keydown", (e) => {
    if (e.target.tagName === "SELECT") return;
    if (e.key === "p" || e.key === "P") setTool("pose");
    else if (e.key === "g" || e.key === "G") setTool("goal");
    else if (e.key === "Escape") {
      pointer.drag = null;
      setTool("pan");
      redraw();
    }
  });
}

export function bindTools() {
  bindPanel();
  bindMouse();
  bindKeys();
}
