// The one WebSocket to the viewer server: connect (and reconnect with back-off), send a command, and hand every
// parsed message to the handler given to connect().

import { log, setConnected } from "./panels.js";
import { show } from "./state.js";

let ws = null;
let retry = 500;

export function send(msg) {
  if (ws && ws.readyState === WebSocket.OPEN) {
    ws.send(JSON.stringify(msg));
    return true;
  }
  log("error", "not connected: nothing sent");
  return false;
}

/** Tell the server which optional grid layers to send (it sends only those). */
export function sendLayers() {
  const layers = ["global_costmap", "local_costmap"].filter((n) => show[n]);
  send({ type: "layers", layers });
}

export function connect(onMessage) {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  // A viewer listening beyond loopback asks for its launch token: pass on the one this page was opened with.
  const token = new URLSearchParams(location.search).get("token");
  const query = token ? `?token=${encodeURIComponent(token)}` : "";
  ws = new WebSocket(`${proto}://${location.host}/ws${query}`);
  ws.onopen = () => {
    retry = 500;
    setConnected(true);
  };
  ws.onclose = () => {
    setConnected(false);
    setTimeout(() => connect(onMessage), retry);
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
    onMessage(m);
  };
}
