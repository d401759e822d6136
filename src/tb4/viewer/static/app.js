// tb4 viewer front end: one WebSocket, one canvas. The server sends bounded-rate `state` snapshots and grid
// `layer` images; this file keeps the newest of each and redraws (at most once per animation frame) on change.
// window.tb4State mirrors what is shown, and window.tb4View converts coordinates, so tests can check the page.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const canvas = $("view");
  const ctx = canvas.getContext("2d");

  const COLORS = {
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
  const MAX_TRAIL = 8000; // points kept on the page
  const MAX_LOG = 40;

  // Everything shown, and what tests read.
  const S = (window.tb4State = {
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
    tool: "pan",
    stateCount: 0,
    frames: 0,
    errors: [],
    acks: [],
    lastError: null,
  });
  const view = { cx: 0, cy: 0, scale: 20, fitted: false, follow: false };
  const show = { global_costmap: true, local_costmap: true, scan: true, plan: true, trail: true, places: true };

  // --- coordinates ---------------------------------------------------------------------------------------------
  const size = () => ({ w: canvas.clientWidth, h: canvas.clientHeight });
  function worldToScreen(x, y) {
    const { w, h } = size();
    return [w / 2 + (x - view.cx) * view.scale, h / 2 - (y - view.cy) * view.scale];
  }
  function screenToWorld(px, py) {
    const { w, h } = size();
    return [view.cx + (px - w / 2) / view.scale, view.cy - (py - h / 2) / view.scale];
  }
  function worldToPage(x, y) {
    const r = canvas.getBoundingClientRect();
    const [px, py] = worldToScreen(x, y);
    return [r.left + px, r.top + py];
  }
  function fitMap() {
    const map = S.layers.map;
    if (!map) return false;
    const { w, h } = size();
    const mw = map.width * map.resolution;
    const mh = map.height * map.resolution;
    view.cx = map.origin[0] + mw / 2;
    view.cy = map.origin[1] + mh / 2;
    view.scale = Math.max(0.5, Math.min((w - 20) / mw, (h - 20) / mh));
    view.fitted = true;
    redraw();
    return true;
  }
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

  // --- drawing --------------------------------------------------------------------------------------------------
  let dirty = true;
  function redraw() {
    dirty = true;
  }

  function resize() {
    const dpr = window.devicePixelRatio || 1;
    const { w, h } = size();
    canvas.width = Math.max(1, Math.round(w * dpr));
    canvas.height = Math.max(1, Math.round(h * dpr));
    redraw();
  }

  function drawLayer(layer, alpha) {
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

  function polyline(flat, color, width, dash) {
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

  function arrow(x, y, yaw, color, length) {
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

  function drawPlaces() {
    const world = S.world;
    if (!world) return;
    if (world.route_graph) drawRouteGraph(world.route_graph);
    const d = world.dock;
    if (d) {
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
      label("dock", px + s * 0.6, py + 4, COLORS.dock);
    }
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
  }

  function drawRobot(r) {
    const [px, py] = worldToScreen(r.x, r.y);
    const rad = Math.max(5, r.radius * view.scale);
    ctx.beginPath();
    ctx.arc(px, py, rad + 2, 0, 2 * Math.PI); // a light halo keeps the robot visible on any background
    ctx.fillStyle = "rgba(255, 255, 255, 0.85)";
    ctx.fill();
    ctx.beginPath();
    ctx.arc(px, py, rad, 0, 2 * Math.PI);
    ctx.fillStyle = r.localized ? "rgba(63, 167, 255, 0.55)" : "rgba(160, 160, 170, 0.55)";
    ctx.fill();
    ctx.lineWidth = 2;
    ctx.strokeStyle = r.localized ? COLORS.robotEdge : "#555";
    ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(px, py);
    ctx.lineTo(px + Math.cos(r.yaw) * rad * 1.6, py - Math.sin(r.yaw) * rad * 1.6);
    ctx.lineWidth = 3;
    ctx.strokeStyle = "#0b1320";
    ctx.stroke();
    ctx.beginPath();
    ctx.arc(px, py, Math.max(2.5, rad * 0.25), 0, 2 * Math.PI);
    ctx.fillStyle = COLORS.robot;
    ctx.fill();
    S.robotScreen = { x: px, y: py, radius: rad };
  }

  function drawScaleBar() {
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
    if (S.particles && S.particles.length) {
      ctx.fillStyle = COLORS.particles;
      for (let i = 0; i < S.particles.length; i += 2) {
        const [px, py] = worldToScreen(S.particles[i], S.particles[i + 1]);
        ctx.fillRect(px - 1, py - 1, 2, 2);
      }
    }
    if (show.scan && S.scan.length) {
      ctx.fillStyle = COLORS.scan;
      const d = Math.max(3, Math.min(6, 0.06 * view.scale));
      for (let i = 0; i < S.scan.length; i += 2) {
        const [px, py] = worldToScreen(S.scan[i], S.scan[i + 1]);
        ctx.fillRect(px - d / 2, py - d / 2, d, d);
      }
    }
    S.waypoints.forEach((w, i) => {
      const [px, py] = worldToScreen(w.x, w.y);
      ctx.beginPath();
      ctx.arc(px, py, 8, 0, 2 * Math.PI);
      ctx.fillStyle = w.status === 1 ? "rgba(38, 194, 129, 0.9)" : COLORS.waypoint;
      ctx.fill();
      ctx.fillStyle = "#1b1b1b";
      ctx.font = "600 10px system-ui, sans-serif";
      ctx.fillText(String(i + 1), px - 3, py + 4);
    });
    if (S.goal) arrow(S.goal.x, S.goal.y, S.goal.yaw, COLORS.goal);
    if (S.robot) drawRobot(S.robot);
    else S.robotScreen = null;
    drawScaleBar();
    if (drag && drag.tool !== "pan") {
      arrow(drag.x, drag.y, drag.yaw, drag.tool === "pose" ? COLORS.pose : COLORS.goal, 40);
    }
  }

  function frame() {
    if (dirty) {
      dirty = false;
      draw();
    }
    requestAnimationFrame(frame);
  }

  // --- panel ----------------------------------------------------------------------------------------------------
  function log(level, text) {
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
    num(v, digits, unit) {
      return v == null ? "–" : `${v.toFixed(digits)}${unit || ""}`;
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
      ring.replaceChildren(...Array.from({ length: 6 }, (_, i) => {
        const led = document.createElement("i");
        const a = ((-30 + 60 * i) * Math.PI) / 180;
        led.style.left = `${50 + 38 * Math.cos(a)}%`;
        led.style.top = `${50 - 38 * Math.sin(a)}%`;
        return led;
      }));
    }
    Array.from(ring.children).forEach((led, i) => {
      const rgb = leds[i];
      led.style.background = rgb ? `rgb(${rgb[0]}, ${rgb[1]}, ${rgb[2]})` : "transparent";
    });
    ring.title = c.lightring ? (c.lightring.override ? "light ring (set by a program)" : "light ring (the robot's own)") : "light ring: no data";
    const held = c.buttons || {};
    document.querySelectorAll(".c3-button").forEach((b) => b.classList.toggle("held", !!held[b.dataset.button]));
    $("hazards").textContent = c.hazards && c.hazards.length ? `hazards: ${c.hazards.join(", ")}` : "no hazards";
    $("audio").textContent = c.audio_hz ? `♪ ${c.audio_hz} Hz` : "silent";
  }

  function updatePanel() {
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
      ? `${r.x.toFixed(2)}, ${r.y.toFixed(2)}, ${fmt.deg(r.yaw)}${r.localized ? "" : " (odom: not localized)"}`
      : "–";
    $("speed").textContent = r ? `${r.v.toFixed(2)} m/s, ${r.w.toFixed(2)} rad/s` : "–";
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

  function updateNamespaces(list, current) {
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
        })
      );
    }
    select.value = current;
  }

  // --- messages from the server ---------------------------------------------------------------------------------
  function onHello(m) {
    const changed = S.namespace !== null && S.namespace !== m.namespace;
    S.namespace = m.namespace;
    S.namespaces = m.namespaces;
    if (changed) {
      Object.assign(S, { layers: {}, trail: [], plan: [], scan: [], goal: null, waypoints: [], robot: null });
      Object.assign(S, { world: null, task: null });
      view.fitted = false;
    }
    updateNamespaces(m.namespaces, m.namespace);
    sendLayers();
    log("info", `viewing ${m.namespace || "/"}`);
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
    if (m.trail) {
      S.trail = m.trail.reset ? m.trail.points.slice() : S.trail.concat(m.trail.points);
      if (S.trail.length > 2 * MAX_TRAIL) S.trail = S.trail.slice(-2 * MAX_TRAIL);
    }
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

  // --- connection -----------------------------------------------------------------------------------------------
  let ws = null;
  let retry = 500;
  function send(msg) {
    if (ws && ws.readyState === WebSocket.OPEN) {
      ws.send(JSON.stringify(msg));
      return true;
    }
    log("error", "not connected: nothing sent");
    return false;
  }
  window.tb4Send = send;

  function sendLayers() {
    const layers = ["global_costmap", "local_costmap"].filter((n) => show[n]);
    send({ type: "layers", layers });
  }

  function connect() {
    const proto = location.protocol === "https:" ? "wss" : "ws";
    ws = new WebSocket(`${proto}://${location.host}/ws`);
    ws.onopen = () => {
      S.connected = true;
      retry = 500;
      $("connection").className = "dot on";
      $("connection").textContent = "live";
    };
    ws.onclose = () => {
      S.connected = false;
      $("connection").className = "dot off";
      $("connection").textContent = "offline";
      setTimeout(connect, retry);
      retry = Math.min(5000, retry * 2);
    };
    ws.onmessage = (event) => {
      let m;
      try {
        m = JSON.parse(event.data);
      } catch (e) {
        log("error", `bad message from the server: ${e}`);
        return;
      }
      if (m.type === "state") onState(m);
      else if (m.type === "layer") onLayer(m);
      else if (m.type === "hello") onHello(m);
      else if (m.type === "ack") {
        S.acks.push(m);
        if (S.acks.length > 20) S.acks.shift();
        if (m.command !== "layers") log("info", m.message);
      } else if (m.type === "error") {
        S.lastError = m.message;
        S.errors.push(m.message);
        if (S.errors.length > 20) S.errors.shift();
        log("error", m.message);
      }
    };
  }

  // --- tools and mouse ------------------------------------------------------------------------------------------
  let drag = null;
  function setTool(tool) {
    S.tool = tool;
    for (const b of document.querySelectorAll("[data-tool]")) b.classList.toggle("active", b.dataset.tool === tool);
    canvas.className = tool === "pan" ? "" : tool;
  }
  for (const b of document.querySelectorAll("[data-tool]")) b.addEventListener("click", () => setTool(b.dataset.tool));
  $("cancel").addEventListener("click", () => send({ type: "cancel" }));
  document.querySelectorAll(".c3-button").forEach((b) =>
    b.addEventListener("click", () => send({ type: "press", button: b.dataset.button })),
  );
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

  function eventPoint(e) {
    const r = canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  canvas.addEventListener("mousedown", (e) => {
    const [px, py] = eventPoint(e);
    const tool = e.button === 0 ? S.tool : "pan"; // middle/right button always pans
    const [x, y] = screenToWorld(px, py);
    drag = { tool, px, py, x, y, yaw: 0, cx: view.cx, cy: view.cy };
    if (tool === "pan") canvas.classList.add("dragging");
    canvas.focus();
    e.preventDefault();
  });
  window.addEventListener("mousemove", (e) => {
    const [px, py] = eventPoint(e);
    const [wx, wy] = screenToWorld(px, py);
    $("cursor").textContent = `${wx.toFixed(2)}, ${wy.toFixed(2)}`;
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
  window.addEventListener("mouseup", () => {
    if (!drag) return;
    const d = drag;
    drag = null;
    canvas.classList.remove("dragging");
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
    { passive: false }
  );
  window.addEventListener("keydown", (e) => {
    if (e.target.tagName === "SELECT") return;
    if (e.key === "p" || e.key === "P") setTool("pose");
    else if (e.key === "g" || e.key === "G") setTool("goal");
    else if (e.key === "Escape") {
      drag = null;
      setTool("pan");
      redraw();
    }
  });
  window.addEventListener("resize", resize);

  resize();
  connect();
  requestAnimationFrame(frame);
})();
