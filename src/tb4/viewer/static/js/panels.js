// The side panel: the message log, the status lines, the Create 3 face, the current task, the robot list and
// the fleet legend (each robot's colour and task; click one to command it).

import { $ } from "./canvas.js";
import { S } from "./state.js";

let pickHandler = () => {};
/** What clicking a robot in the fleet legend does (tools.js sends the namespace command). */
export function onPick(handler) {
  pickHandler = handler;
}

const MAX_LOG = 40;

export function log(level, text) {
  const li = document.createElement("li");
  li.className = level;
  const t = document.createElement("span");
  t.className = "t";
  t.textContent = new Date().toLocaleTimeString();
  li.append(t, document.createTextNode(text));
  const list = $("log");
  list.prepend(li);
  while (list.children.length > MAX_LOG) list.lastChild.remove();
}

const fmt = {
  time(s) {
    if (s == null) return "–";
    const m = Math.floor(s / 60);
    return `${m}:${(s - m * 60).toFixed(1).padStart(4, "0")}`;
  },
  deg(rad) {
    return `${Math.round((rad * 180) / Math.PI)}°`;
  },
};

function updateCreate3() {
  const c = S.create3 || {};
  const ring = $("lightring");
  const leds = (c.lightring && c.lightring.leds) || [];
  // LightringLeds index 0 is at 4 o'clock, then counter-clockwise every 60 degrees (2, 12, 10, 8, 6 o'clock)
  if (ring.children.length !== 6) {
    ring.replaceChildren(
      ...Array.from({ length: 6 }, (_, i) => {
        const led = document.createElement("i");
        const a = ((-30 + 60 * i) * Math.PI) / 180;
        led.style.left = `${50 + 38 * Math.cos(a)}%`;
        led.style.top = `${50 - 38 * Math.sin(a)}%`;
        return led;
      }),
    );
  }
  Array.from(ring.children).forEach((led, i) => {
    const rgb = leds[i];
    led.style.background = rgb ? `rgb(${rgb[0]}, ${rgb[1]}, ${rgb[2]})` : "transparent";
  });
  ring.title = c.lightring
    ? c.lightring.override
      ? "light ring (set by a program)"
      : "light ring (the robot's own)"
    : "light ring: no data";
  const held = c.buttons || {};
  document.querySelectorAll(".c3-button").forEach((b) => b.classList.toggle("held", !!held[b.dataset.button]));
  $("hazards").textContent = c.hazards && c.hazards.length ? `hazards: ${c.hazards.join(", ")}` : "no hazards";
  $("audio").textContent = c.audio_hz ? `♪ ${c.audio_hz} Hz` : "silent";
}

function updateTask() {
  const t = S.task;
  const box = $("task");
  box.replaceChildren();
  if (!t) {
    box.textContent = "no task yet";
    return;
  }
  const head = document.createElement("div");
  head.innerHTML = `<span class="name"></span> <span class="state-${t.status}"></span>`;
  head.firstChild.textContent = t.action;
  head.lastChild.textContent = t.status;
  box.append(head);
  const parts = [];
  if (t.eta != null && t.active) parts.push(`ETA ${fmt.time(t.eta)}`);
  if (t.distance_remaining != null) parts.push(`${t.distance_remaining.toFixed(1)} m to go`);
  if (t.navigation_time != null) parts.push(`driving ${fmt.time(t.navigation_time)}`);
  if (t.recoveries) parts.push(`${t.recoveries} recover${t.recoveries === 1 ? "y" : "ies"}`);
  if (t.poses_remaining != null) parts.push(`${t.poses_remaining} pose(s) left`);
  if (t.current_waypoint != null) parts.push(`waypoint ${t.current_waypoint + 1}`);
  if (parts.length) {
    const line = document.createElement("div");
    line.textContent = parts.join(" · ");
    box.append(line);
  }
}

export function updatePanel() {
  updateCreate3();
  $("sim-time").textContent = fmt.time(S.simTime);
  $("rtf").textContent = S.rtf == null ? "–" : `${S.rtf.toFixed(S.rtf < 10 ? 2 : 1)}×`;
  const b = S.battery;
  $("battery").textContent = b && b.percentage != null ? `${Math.round(b.percentage * 100)} % ${b.status}` : "–";
  $("battery-meter").value = b && b.percentage != null ? b.percentage : 0;
  const d = S.dock;
  $("dock").textContent = d ? (d.is_docked ? "docked" : d.dock_visible ? "undocked, dock in view" : "undocked") : "–";
  const r = S.robot;
  $("pose").textContent = r
    ? `${r.x.toFixed(2)}, ${r.y.toFixed(2)}, ${fmt.deg(r.yaw)}${r.localized ? "" : ` (${r.frame}: not localized)`}`
    : "–";
  $("speed").textContent = r ? `${r.v.toFixed(2)} m/s, ${r.w.toFixed(2)} rad/s` : "–";
  updateTask();
}

export function updateNamespaces(list, current) {
  const select = $("namespace");
  const names = Array.from(new Set([...(list || []), current]));
  const key = names.join("|");
  if (select.dataset.key !== key) {
    select.dataset.key = key;
    select.replaceChildren(
      ...names.map((ns) => {
        const o = document.createElement("option");
        o.value = ns;
        o.textContent = ns || "/ (no namespace)";
        return o;
      }),
    );
  }
  select.value = current;
}

function fleetStatus(r) {
  const task = r.picked ? S.task : r.task;
  return task ? `${task.action.replaceAll("_", " ")}: ${task.status}` : "idle";
}

export function updateFleet() {
  const section = $("fleet-section");
  section.hidden = S.fleet.length === 0;
  const list = $("fleet");
  const key = S.fleet.map((r) => `${r.namespace}:${r.color}:${r.picked}`).join("|");
  if (list.dataset.key !== key) {
    list.dataset.key = key;
    list.replaceChildren(
      ...S.fleet.map((r) => {
        const li = document.createElement("li");
        li.dataset.namespace = r.namespace;
        li.className = r.picked ? "picked" : "";
        li.title = r.picked ? "the robot the tools command" : `command ${r.namespace} with the tools`;
        const swatch = document.createElement("i");
        swatch.className = "swatch";
        swatch.style.background = r.color;
        const name = document.createElement("span");
        name.className = "name";
        name.textContent = r.namespace;
        const status = document.createElement("span");
        status.className = "status";
        li.append(swatch, name, status);
        li.addEventListener("click", () => pickHandler(r.namespace));
        return li;
      }),
    );
  }
  Array.from(list.children).forEach((li, i) => {
    li.lastChild.textContent = fleetStatus(S.fleet[i]);
  });
}

export function setConnected(live) {
  S.connected = live;
  $("connection").className = live ? "dot on" : "dot off";
  $("connection").textContent = live ? "live" : "offline";
}
