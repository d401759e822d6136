// tb4 viewer front end: one WebSocket, one canvas, as ES modules (no build step), one job each:
//   js/state.js       what is shown (window.tb4State, read by the tests), the view, the redraw flag
//   js/canvas.js      the canvas and world <-> screen coordinates
//   js/map_draw.js    grid layers, plan and trail, docks/places/route graph, arrows, scale bar
//   js/robot_draw.js  robot, particles, scan, waypoints
//   js/render.js      one frame, at most once per animation frame after a change
//   js/panels.js      the side panel (status, Create 3, task, log, namespaces)
//   js/connection.js  the WebSocket;  js/messages.js  what each server message changes
//   js/tools.js       pose/goal/pan tools, mouse, keys, buttons
// window.tb4View converts coordinates and window.tb4Send sends a command, so tests can drive the page.

import { fitMap, resize, screenToWorld, worldToPage, worldToScreen } from "./js/canvas.js";
import { connect, send } from "./js/connection.js";
import { onMessage } from "./js/messages.js";
import { startRendering } from "./js/render.js";
import { redraw, view } from "./js/state.js";
import { bindTools } from "./js/tools.js";

window.tb4View = {
  worldToScreen,
  screenToWorld,
  worldToPage,
  fitMap,
  setView(cx, cy, scale) {
    Object.assign(view, { cx, cy, scale: scale || view.scale, fitted: true });
    redraw();
  },
  get view() {
    return { ...view };
  },
};
window.tb4Send = send;

bindTools();
window.addEventListener("resize", resize);
resize();
connect(onMessage);
startRendering();
