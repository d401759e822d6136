// What the page shows and how it looks at it: the state mirrored from the server (window.tb4State, which the
// tests read), the view (centre and scale), the layer switches, the drag in progress, and the redraw flag.

export const COLORS = {
  scan: "#ff3b30",
  plan: "#2ee66b",
  trail: "#ffb020",
  robot: "#3fa7ff",
  robotEdge: "#0b3d73",
  pose: "#26c281",
  goal: "#ff5fa2",
  amcl: "rgba(38, 194, 129, 0.9)",
  particles: "rgba(0, 120, 255, 0.55)",
  place: "#8a7dff",
  dock: "#f4d35e",
  waypoint: "#ffd166",
  background: "#2b3442",
};
export const MAX_TRAIL = 8000; // points kept on the page
// One colour per robot of a fleet, by its place in the fleet (robot1 keeps the one-robot blue); a robot in no
// fleet is drawn in COLORS as always.
export const FLEET_COLORS = ["#3fa7ff", "#ff8c1a", "#c46bff", "#19c9a6", "#ffd21f", "#ff4f7b", "#8bd346", "#a0785a"];
export const fleetColor = (index) => FLEET_COLORS[index % FLEET_COLORS.length];

export const S = (window.tb4State = {
  connected: false,
  namespace: null,
  namespaces: [],
  layers: {}, // name -> {version, width, height, resolution, origin, frame, image}
  world: null,
  robot: null,
  robotScreen: null,
  scan: [],
  plan: [],
  trail: [],
  goal: null,
  waypoints: [],
  amcl: null,
  battery: null,
  dock: null,
  task: null,
  simTime: null,
  rtf: null,
  fleet: [], // the commanded robot's fleet in order: {namespace, color, picked, robot, goal, plan, trail, task}
  color: null, // the commanded robot's fleet colour (null: not in a fleet)
  fleetScreen: [], // where each drawn fleet robot is on screen, for picking one with a click
  docksScreen: [], // each dock drawn: its label, its station's centre on screen and the dock pose it stands for
  tool: "pan",
  stateCount: 0,
  frames: 0,
  errors: [],
  acks: [],
  lastError: null,
});
export const view = { cx: 0, cy: 0, scale: 20, fitted: false, follow: false };
export const show = { global_costmap: true, local_costmap: true, scan: true, plan: true, trail: true, places: true };
export const pointer = { drag: null }; // the mouse drag in progress (tools.js), drawn as a pose arrow

let dirty = true;
export function redraw() {
  dirty = true;
}
export function takeRedraw() {
  const was = dirty;
  dirty = false;
  return was;
}
