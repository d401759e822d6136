// The canvas and the mapping between world coordinates (metres, y up) and screen pixels (y down).

import { redraw, S, view } from "./state.js";

export const $ = (id) => document.getElementById(id);
export const canvas = $("view");
export const ctx = canvas.getContext("2d");

export const size = () => ({ w: canvas.clientWidth, h: canvas.clientHeight });

export function worldToScreen(x, y) {
  const { w, h } = size();
  return [w / 2 + (x - view.cx) * view.scale, h / 2 - (y - view.cy) * view.scale];
}

export function screenToWorld(px, py) {
  const { w, h } = size();
  return [view.cx + (px - w / 2) / view.scale, view.cy - (py - h / 2) / view.scale];
}

export function worldToPage(x, y) {
  const r = canvas.getBoundingClientRect();
  const [px, py] = worldToScreen(x, y);
  return [r.left + px, r.top + py];
}

export function fitMap() {
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

export function resize() {
  const dpr = window.devicePixelRatio || 1;
  const { w, h } = size();
  canvas.width = Math.max(1, Math.round(w * dpr));
  canvas.height = Math.max(1, Math.round(h * dpr));
  redraw();
}
