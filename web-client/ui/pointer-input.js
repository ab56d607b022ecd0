// Mouse, pen, touch and trackpad on the canvas, turned into camera moves and sculpting. Which
// press starts which gesture is ui/gesture-map.js (sculpt on the model, with Ctrl to
// invert, Shift to smooth and Alt to pick the colour; Space+drag or right drag orbits anywhere; middle drag pans;
// F+drag sizes the brush); an orbit turns around the surface point under the pointer where
// the press began (or the last point the brush was on); a double press that orbits without
// moving (a double right-click, Space+double-click, or a double-click beside the model)
// centres the view on the point under the pointer; the wheel zooms towards the point under the
// pointer (a trackpad pinch arrives as Ctrl+wheel); two fingers pinch to zoom, move together
// to pan and turn to orbit; a quick two-finger tap undoes.
// Conventions: positions in CSS pixels relative to the canvas's top-left corner (y down);
// pressure in (0, 1]: the pen's, 1 for a mouse (whose Pointer Events pressure is a constant
// 0.5 while a button is down), and 1 for touch screens that report none. A finger's stroke
// starts when it moves CLICK_SLOP_PX, stays TOUCH_HOLD_MS, or lifts (a tap is one dab), so a
// pinch that begins on the model does not dab.

import { pressGesture } from "./gesture-map.js";
import { isTyping } from "./shortcuts.js";

const CLICK_SLOP_PX = 4;
const MIN_PRESSURE = 0.05;
const MAX_COALESCED = 16;
const TOUCH_HOLD_MS = 120; // a finger that stays this long on the model starts its stroke
const HELD_KEYS = new Set(["Space", "KeyF"]);
// Times are the events' own (timeStamp), not when a busy page got round to handling them.
const DOUBLE_MS = 400; // two still camera presses this close in time are a double press
const TAP_MS = 250; // two fingers down and up within this, without moving: a two-finger tap


export class PointerInput {
  constructor(canvas, camera, handlers) {
    this.canvas = canvas;
    this.camera = camera;
    this.h = handlers;
    this.gesture = null; // {kind, pointerId, x, y, startX, startY}
    this.touches = new Map(); // pointerId -> [x, y]
    canvas.addEventListener("pointerdown", (e) => this.#down(e));
    canvas.addEventListener("pointermove", (e) => this.#move(e));
    canvas.addEventListener("pointerup", (e) => this.#up(e, false));
    canvas.addEventListener("pointercancel", (e) => this.#up(e, true));
    canvas.addEventListener("pointerleave", (e) => {
      if (!this.gesture && e.pointerType !== "touch") this.h.leave();
    });
    canvas.addEventListener("wheel", (e) => this.#wheel(e), { passive: false });
    canvas.addEventListener("contextmenu", (e) => e.preventDefault());
    // Keys held for a gesture: Space (orbit or pan anywhere) and F (brush size).
    this.held = new Set();
    const doc = canvas.ownerDocument;
    doc.addEventListener("keydown", (e) => {
      if (!HELD_KEYS.has(e.code) || isTyping(e.target)) return;
      this.held.add(e.code);
      if (e.target === canvas || e.target === doc.body) e.preventDefault(); // Space would scroll
    });
    doc.addEventListener("keyup", (e) => this.held.delete(e.code));
    doc.defaultView.addEventListener("blur", () => this.held.clear());
  }

  // Ends whatever gesture runs (Escape, a lost connection, a second finger).
  cancel() {
    if (this.gesture && this.gesture.kind === "stroke") this.h.strokeEnd();
    if (this.gesture) clearTimeout(this.gesture.timer);
    this.#setGesture(null);
  }

  #pos(e) {
    const r = this.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  #pressure(e) {
    if (e.pointerType === "mouse" || !(e.pressure > 0)) return 1;
    return Math.min(1, Math.max(MIN_PRESSURE, e.pressure));
  }

  #setGesture(g) {
    this.gesture = g;
    this.canvas.dataset.gesture = g ? g.kind : "";
  }

  #down(e) {
    this.canvas.focus({ preventScroll: true });
    const [x, y] = this.#pos(e);
    if (e.pointerType === "touch") {
      this.touches.set(e.pointerId, [x, y]);
      if (this.touches.size === 2) {
        this.cancel();
        const state = this.#pinchState();
        this.#setGesture({ kind: "pinch", ...state, at: e.timeStamp, startDistance: state.distance, startMid: state.mid, moved: false });
        return;
      }
      if (this.touches.size > 2) return;
    }
    if (this.gesture) return;
    const press = {
      button: e.button,
      ctrl: e.ctrlKey || e.metaKey,
      alt: e.altKey,
      shift: e.shiftKey,
      space: this.held.has("Space"),
      brushKey: this.held.has("KeyF"),
    };
    const needsSurface = e.button === 0 && !press.space && !press.brushKey;
    const chosen = pressGesture(press, needsSurface ? this.h.sculptGestureAt(x, y) : null);
    if (!chosen) return;
    const g = { pointerId: e.pointerId, x, y, startX: x, startY: y, kind: chosen.kind, modifier: chosen.modifier, at: e.timeStamp };
    if (g.kind === "orbit") g.pivot = this.h.pivotAt(x, y);
    if (g.kind === "brush") this.h.brushStart();
    try {
      this.canvas.setPointerCapture(e.pointerId);
    } catch {
      // A pointer the browser no longer tracks cannot be captured; the gesture still works
      // while the pointer stays over the canvas.
    }
    // A finger on the model may be the first of a pinch: its stroke starts only once it moves
    // or stays, so that a second finger arriving first makes a pinch without a dab.
    if (g.kind === "stroke" && e.pointerType === "touch") {
      g.kind = "touch-pending";
      g.pressure = this.#pressure(e);
      g.timer = setTimeout(() => this.#startPendingStroke(), TOUCH_HOLD_MS);
    }
    this.#setGesture(g);
    if (g.kind === "stroke") this.h.strokeStart(x, y, this.#pressure(e), g.modifier);
    if (g.kind === "pick") this.h.pickColor(x, y);
    e.preventDefault();
  }

  #move(e) {
    const [x, y] = this.#pos(e);
    if (e.pointerType === "touch" && this.touches.has(e.pointerId)) this.touches.set(e.pointerId, [x, y]);
    const g = this.gesture;
    if (!g) {
      if (e.pointerType !== "touch") this.h.hover(x, y);
      return;
    }
    if (g.kind === "pinch") return this.#pinch();
    if (e.pointerId !== g.pointerId) return;
    const dx = x - g.x, dy = y - g.y;
    g.x = x;
    g.y = y;
    const height = this.canvas.clientHeight;
    switch (g.kind) {
      case "orbit":
        this.camera.orbit(dx, dy, height, g.pivot);
        this.h.cameraChanged();
        break;
      case "pan":
        this.camera.pan(dx, dy, height);
        this.h.cameraChanged();
        break;
      case "brush":
        this.h.brushDrag(x - g.startX, y - g.startY);
        break;
      case "click":
        if (Math.hypot(x - g.startX, y - g.startY) > CLICK_SLOP_PX) g.kind = "orbit";
        break;
      case "touch-pending":
        if (Math.hypot(x - g.startX, y - g.startY) > CLICK_SLOP_PX) {
          this.#startPendingStroke();
          this.h.strokeMove(x, y, this.#pressure(e));
        }
        break;
      case "stroke": {
        const samples = e.getCoalescedEvents ? e.getCoalescedEvents().slice(-MAX_COALESCED) : [];
        if (!samples.length) samples.push(e);
        for (const s of samples) {
          const [sx, sy] = this.#pos(s);
          this.h.strokeMove(sx, sy, this.#pressure(s));
        }
        break;
      }
    }
  }

  #up(e, cancelled) {
    if (e.pointerType === "touch") {
      this.touches.delete(e.pointerId);
      const pinch = this.gesture && this.gesture.kind === "pinch" ? this.gesture : null;
      if (pinch) {
        if (this.touches.size < 2) {
          this.#setGesture(null);
          if (!cancelled && !pinch.moved && e.timeStamp - pinch.at < TAP_MS) this.h.twoFingerTap();
        }
        return;
      }
    }
    const g = this.gesture;
    if (!g || e.pointerId !== g.pointerId) return;
    if (this.canvas.hasPointerCapture(e.pointerId)) this.canvas.releasePointerCapture(e.pointerId);
    if (g.kind === "touch-pending" && !cancelled) this.#startPendingStroke(); // a tap: one dab
    clearTimeout(g.timer);
    this.#setGesture(null);
    if (g.kind === "stroke") this.h.strokeEnd();
    else if (g.kind === "click" && !cancelled) this.h.click(g.startX, g.startY, g.modifier);
    else if ((g.kind === "orbit" || g.kind === "pan") && !cancelled) this.#stillPress(g);
    if (e.pointerType !== "touch") this.h.hover(...this.#pos(e));
  }

  // A camera press that did not move: two in a row, close in time and place, focus the view on
  // the surface point under the pointer.
  #stillPress(g) {
    if (Math.hypot(g.x - g.startX, g.y - g.startY) > CLICK_SLOP_PX) return (this.lastStill = null);
    const last = this.lastStill;
    if (last && g.at - last.at < DOUBLE_MS && Math.hypot(g.startX - last.x, g.startY - last.y) <= 2 * CLICK_SLOP_PX) {
      this.lastStill = null;
      this.h.focusAt(g.startX, g.startY);
    } else {
      this.lastStill = { at: g.at, x: g.startX, y: g.startY };
    }
  }

  #startPendingStroke() {
    const g = this.gesture;
    if (!g || g.kind !== "touch-pending") return;
    clearTimeout(g.timer);
    g.kind = "stroke";
    this.canvas.dataset.gesture = "stroke";
    this.h.strokeStart(g.startX, g.startY, g.pressure, g.modifier);
  }

  #pinchState() {
    const [a, b] = [...this.touches.values()];
    return {
      distance: Math.hypot(a[0] - b[0], a[1] - b[1]),
      mid: [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2],
      angle: Math.atan2(b[1] - a[1], b[0] - a[0]),
    };
  }

  #pinch() {
    if (this.touches.size < 2) return;
    const g = this.gesture;
    const now = this.#pinchState();
    if (g.distance > 0 && now.distance > 0) this.camera.zoom(g.distance / now.distance);
    this.camera.pan(now.mid[0] - g.mid[0], now.mid[1] - g.mid[1], this.canvas.clientHeight);
    // Turning the two fingers orbits: a quarter turn of the fingers is a quarter turn of the model.
    const twist = wrapAngle(now.angle - g.angle);
    if (twist) this.camera.orbit((-twist * this.canvas.clientHeight) / Math.PI, 0, this.canvas.clientHeight);
    if (Math.abs(now.distance - g.startDistance) > CLICK_SLOP_PX || Math.hypot(now.mid[0] - g.startMid[0], now.mid[1] - g.startMid[1]) > CLICK_SLOP_PX)
      g.moved = true;
    g.distance = now.distance;
    g.mid = now.mid;
    g.angle = now.angle;
    this.h.cameraChanged();
  }

  #wheel(e) {
    e.preventDefault();
    const unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? this.canvas.clientHeight : 1;
    const delta = e.deltaY * unit;
    const [x, y] = this.#pos(e);
    this.camera.zoomAt(Math.exp(delta * (e.ctrlKey ? 0.01 : 0.0015)), x, y, this.canvas.clientWidth, this.canvas.clientHeight);
    this.h.cameraChanged();
  }
}

function wrapAngle(a) {
  return a - 2 * Math.PI * Math.floor((a + Math.PI) / (2 * Math.PI));
}
