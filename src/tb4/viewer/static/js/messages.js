// What each message from the server changes: `hello` (namespace), `layer` (a grid image), `state` (a snapshot),
// `ack` and `error` (answers to the page's commands).

import { fitMap } from "./canvas.js";
import { sendLayers } from "./connection.js";
import { log, updateFleet, updateNamespaces, updatePanel } from "./panels.js";
import { fleetColor, MAX_TRAIL, redraw, S, view } from "./state.js";

const MAX_KEPT = 20; // acks and errors kept for the tests

function appendTrail(trail, update) {
  const points = update.reset ? update.points.slice() : trail.concat(update.points);
  return points.length > 2 * MAX_TRAIL ? points.slice(-2 * MAX_TRAIL) : points;
}

/** The fleet of the commanded robot: every other robot's overview merged into what the page already has. */
function onFleet(entries) {
  const before = new Map(S.fleet.map((r) => [r.namespace, r]));
  S.fleet = entries.map((e, i) => {
    const color = fleetColor(i);
    if (e.picked) return { namespace: e.namespace, color, picked: true };
    const old = before.get(e.namespace);
    const robot = { namespace: e.namespace, color, picked: false, robot: e.robot, goal: e.goal, task: e.task };
    robot.plan = e.plan || (old && !old.picked ? old.plan : []);
    const trail = old && !old.picked ? old.trail : [];
    robot.trail = e.trail ? appendTrail(trail, e.trail) : trail;
    return robot;
  });
  const picked = S.fleet.find((r) => r.picked);
  S.color = picked ? picked.color : null;
}

function onHello(m) {
  const changed = S.namespace !== null && S.namespace !== m.namespace;
  S.namespace = m.namespace;
  S.namespaces = m.namespaces;
  if (changed) {
    // Another robot of the same fleet shares the world: keep the map, the world and the view, drop the rest.
    const sameWorld = S.fleet.some((r) => r.namespace === m.namespace);
    const layers = sameWorld && S.layers.map ? { map: { ...S.layers.map, version: -1 } } : {}; // replaced when sent
    Object.assign(S, { layers, trail: [], plan: [], scan: [], goal: null, waypoints: [], robot: null, task: null });
    if (!sameWorld) {
      Object.assign(S, { world: null, fleet: [], color: null });
      view.fitted = false;
    }
  }
  updateNamespaces(m.namespaces, m.namespace);
  updateFleet();
  sendLayers();
  log("info", `${S.fleet.length ? "commanding" : "viewing"} ${m.namespace || "/"}`);
  redraw();
}

function onLayer(m) {
  const img = new Image();
  img.onload = () => {
    const current = S.layers[m.name];
    if (current && current.version > m.version) return;
    S.layers[m.name] = { ...m, png: undefined, image: img };
    if (m.name === "map" && !view.fitted) fitMap();
    redraw();
  };
  img.src = `data:image/png;base64,${m.png}`;
}

function onState(m) {
  S.stateCount += 1;
  S.simTime = m.sim_time;
  S.rtf = m.rtf;
  S.robot = m.robot;
  S.scan = m.scan || [];
  S.battery = m.battery;
  S.dock = m.dock;
  S.create3 = m.create3;
  S.task = m.task;
  S.goal = m.goal;
  S.waypoints = m.waypoints || [];
  S.amcl = m.amcl;
  S.particles = m.particles || [];
  if (m.plan) S.plan = m.plan.points;
  if (m.trail) S.trail = appendTrail(S.trail, m.trail);
  onFleet(m.fleet || []);
  updateFleet();
  if ("world" in m) S.world = m.world;
  for (const n of m.notices || []) log(n.level, n.text);
  if (m.namespaces) {
    S.namespaces = m.namespaces;
    updateNamespaces(m.namespaces, S.namespace);
  }
  if (view.follow && S.robot) {
    view.cx = S.robot.x;
    view.cy = S.robot.y;
  }
  updatePanel();
  redraw();
}

function keep(list, item) {
  list.push(item);
  if (list.length > MAX_KEPT) list.shift();
}

export function onMessage(m) {
  if (m.type === "state") onState(m);
  else if (m.type === "layer") onLayer(m);
  else if (m.type === "hello") onHello(m);
  else if (m.type === "ack") {
    keep(S.acks, m);
    if (m.command !== "layers") log("info", m.message);
  } else if (m.type === "error") {
    S.lastError = m.message;
    keep(S.errors, m.message);
    log("error", m.message);
  }
}
