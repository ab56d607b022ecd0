// Sculpting with the pointer: the brush cursor under the pointer, strokes of brush dabs, and
// clicks of CSG tools.
// Conventions: pointer positions in CSS pixels of the canvas; world in vu. The surface under
// the pointer is found on the client's splats (math/splat-pick.js): that places the cursor and
// spaces the dabs (DAB_SPACING of the radius apart along the surface). A stroke picks its dabs
// on the surface as it was when the stroke began (the splat store's bricks at the press; the
// store replaces a changed brick's entry, never its arrays, so that list stays intact) and
// sends them as centres: a dab never lands on what the stroke itself just added, so a stroke
// cannot climb its own growth into a tentacle however long the pointer scrubs one place (it
// rises its height, or building up at most about the brush radius, above where it began). Mirror symmetry is the server's (stroke.begin `symmetry`): the cursor shows the
// mirrored images, x' = nx - 1 - x for a mirror across x. A modifier held at the press (ui/
// gesture-map.js) inverts the tool or makes it smooth for that stroke; with the stabiliser on
// (settings.lazy, in CSS pixels) the brush trails the pointer on a string (math/lazy-mouse.js).
// A warp stroke (grab, elastic grab, snake hook, twist, scale, pinch; math/warp-drag.js) picks
// its anchor on the surface at the press and sends it as the first dab; then each pointer
// position as the point where the pointer's ray meets the plane through the anchor facing the
// camera, so the anchor goes where the pointer points (no stabiliser for the anchored ones:
// the grab follows the pointer itself); twist, scale and pinch send the camera's screen-right
// axis as their `direction`, and no warp sends symmetry. A warp whose dabs are a
// "surface_path" (pinch path) strokes as a brush does: its dabs picked on the surface as the
// stroke began, spaced and with pressure, the first starting the path; with the warp strength.

import { DabSpacer } from "../math/dab-spacer.js";
import { brushGhost, pinchFactor, planeGhost, scaleFactor, warpGhost } from "../math/brush-ghost.js";
import { LazyMouse } from "../math/lazy-mouse.js";
import { transformPoint } from "../math/mat4.js";
import { pickSplats } from "../math/splat-pick.js";
import { distance } from "../math/vec3.js";
import { WarpDrag, warpAmount } from "../math/warp-drag.js";
import { LINE_PIXELS } from "../render/brush-cursor.js";
import { DISC_RADIUS } from "../render/splat-renderer.js";
import { StrokeSender } from "../net/stroke-sender.js";
import { BrushDrag } from "./brush-drag.js";
import { toolById, toolWithModifier } from "./tools.js";

export const DAB_SPACING = 0.25;

export class Sculpt {
  constructor({ session, store, camera, renderer, controls, messages }) {
    Object.assign(this, { session, store, camera, renderer, controls, messages });
    this.hoverAt = null; // [x, y] of the pointer over the canvas, or null
    this.hit = null; // the surface under it
    this.lastPoint = null; // the last surface point the pointer was on (the orbit pivot beside the model)
    this.stroke = null; // {sender, spacer}
    this.openStrokes = 0; // strokes whose stroke.end has not answered yet
    this.onCursor = () => {}; // the brush under the pointer moved, or a stroke began or ended (presence)
    renderer.onBeforeDraw.push(() => this.stroke && this.stroke.sender.flush());
  }

  get editable() {
    return this.session.connected && !this.session.readOnly;
  }

  // The surface under the pointer at (x, y): {t, point, normal} or null; on `bricks` (default:
  // the splats as they are now).
  pick(x, y, bricks = this.store.bricks.values()) {
    const { origin, direction } = this.#ray(x, y);
    return pickSplats(bricks, origin, direction, DISC_RADIUS);
  }

  #ray(x, y) {
    return this.camera.ray(x, y, this.renderer.canvas.clientWidth, this.renderer.canvas.clientHeight);
  }

  hover(x, y) {
    this.hoverAt = [x, y];
    this.hit = this.pick(x, y);
    if (this.hit) this.lastPoint = this.hit.point;
    this.#updateCursor();
  }

  // The point an orbit starting at (x, y) turns around: the surface under the pointer, else
  // the last surface point the pointer was on, else none (the camera's target).
  pivotAt(x, y) {
    const hit = this.pick(x, y);
    if (hit) this.lastPoint = hit.point;
    return hit ? hit.point : this.lastPoint || null;
  }

  leave() {
    this.hoverAt = null;
    this.hit = null;
    this.#updateCursor();
  }

  // The settings or the view changed: the cursor follows.
  refresh() {
    // a warp's cursor is its drag's, which new splats do not move
    if (this.hoverAt && !(this.stroke && this.stroke.warp)) this.hit = this.pick(...this.hoverAt, this.stroke ? this.stroke.surface : undefined);
    this.#updateCursor();
  }

  // What the others see of this page's brush (PROTOCOL.md "Presence"): {tool, radius, point,
  // normal, active} while the pointer is on the model of a session this page may edit, else
  // null. The tool is the stroke's own while one is open (a modifier may have inverted it).
  get presenceBrush() {
    if (!this.hit || !this.editable) return null;
    const s = this.controls.settings;
    const tool = this.stroke ? this.stroke.tool : s.tool;
    const brush = { tool, radius: s.radius, point: this.hit.point, normal: this.hit.normal, active: Boolean(this.stroke) };
    // a painting sculptor's ring shows in the paint colour
    if (toolById(tool).takes.has("color")) brush.color = [...s.paintColor];
    return brush;
  }

  // Alt+click: the colour of the splat under (x, y) becomes the paint colour.
  pickColor(x, y) {
    const hit = this.pick(x, y);
    if (hit && hit.color) this.controls.setPaintColor(hit.color);
  }

  // "stroke" or "click" when a press at (x, y) sculpts, "blocked" when it lands on the model
  // of a session that is open with edit rights but offline (it does nothing then, not even
  // orbit), null when it should orbit instead.
  sculptGestureAt(x, y) {
    const info = this.session.info;
    if (!info || this.session.readOnly) return null;
    this.hit = this.pick(x, y);
    if (!this.hit) return null;
    return this.session.connected ? this.controls.tool.kind : "blocked";
  }

  strokeStart(x, y, pressure, modifier = null) {
    const s = this.controls.settings;
    const maxDabs = (this.session.info.limits && this.session.info.limits.max_dabs) || 256;
    const tool = toolWithModifier(s.tool, modifier);
    const warp = toolById(tool).warp;
    if (warp && warp !== "surface_path") return this.#warpStart(x, y, toolById(tool), maxDabs);
    this.stroke = {
      tool,
      // add / remove blob strokes have a height set by strength and radius (or build up, the
      // "Build up" option): net/stroke-sender.js strokeBeginParams
      // paint takes the paint colour; a mask stroke with the inverting modifier erases
      sender: new StrokeSender(
        this.session,
        { tool, radius: s.radius, strength: warp ? s.warpStrength : s.strength, symmetry: s.symmetry, buildUp: s.buildUp, color: s.paintColor, erase: modifier === "invert" },
        maxDabs,
      ),
      spacer: new DabSpacer(Math.max(0.25, DAB_SPACING * s.radius)),
      lazy: new LazyMouse(s.lazy || 0),
      surface: [...this.store.bricks.values()], // the splats at the press, for picking its dabs
    };
    this.#startSending();
    this.strokeMove(x, y, pressure);
  }

  #startSending() {
    const sender = this.stroke.sender;
    sender.onPlane = (plane) => {
      if (this.stroke && this.stroke.sender === sender) this.#updateCursor();
    };
    this.#setOpenStrokes(this.openStrokes + 1);
  }

  // The anchor is the surface under the press, on the splats as they are (a press lands on the
  // model: ui/gesture-map.js); it goes as the stroke's first dab.
  #warpStart(x, y, tool, maxDabs) {
    const s = this.controls.settings;
    const hit = this.pick(x, y);
    if (!hit) return;
    this.camera.update(this.renderer.canvas.clientWidth, this.renderer.canvas.clientHeight);
    const anchor = hit.point.map(round);
    const direction = tool.takes.has("direction") ? this.camera.right.map(round) : null;
    const drag = new WarpDrag({ anchor, viewNormal: this.camera.backward, dabs: tool.warp, spacing: Math.max(0.25, DAB_SPACING * s.radius) });
    this.stroke = {
      tool: tool.id,
      warp: { drag, tool, anchorNormal: hit.normal, direction },
      sender: new StrokeSender(this.session, { tool: tool.id, radius: s.radius, strength: s.warpStrength, direction }, maxDabs),
      lazy: new LazyMouse(tool.warp === "path" ? s.lazy || 0 : 0),
    };
    this.stroke.sender.add({ center: anchor });
    this.hit = hit;
    this.hoverAt = [x, y];
    this.#startSending();
    this.#updateCursor();
  }

  #warpMove(x, y) {
    const { drag, anchorNormal } = this.stroke.warp;
    for (const p of drag.move(this.#ray(x, y))) this.stroke.sender.add({ center: p.map(round) });
    // the brush others see (presence) is where the anchor goes
    if (drag.point) this.hit = { t: distance(this.camera.eye, drag.point), point: drag.point, normal: anchorNormal };
    this.#updateCursor();
  }

  strokeMove(px, py, pressure) {
    if (!this.stroke) return;
    const at = this.stroke.lazy.follow(px, py);
    if (!at) return;
    const [x, y] = at;
    this.hoverAt = [x, y];
    if (this.stroke.warp) return this.#warpMove(x, y);
    const surface = this.stroke.surface;
    this.hit = this.pick(x, y, surface);
    for (const dab of this.stroke.spacer.add(this.hit && this.hit.point, [x, y], pressure)) {
      // the spacer interpolates between samples; the dab's own pick puts it on the surface
      const onSurface = this.pick(dab.screen[0], dab.screen[1], surface);
      const center = (onSurface ? onSurface.point : dab.point).map(round);
      this.stroke.sender.add({ center, pressure: round(dab.pressure) });
    }
    this.#updateCursor();
  }

  strokeEnd() {
    if (!this.stroke) return;
    const { sender, warp } = this.stroke;
    if (warp) for (const p of warp.drag.end()) sender.add({ center: p.map(round) });
    this.stroke = null;
    if (warp && this.hoverAt) this.hit = this.pick(...this.hoverAt);
    sender.end().finally(() => this.#setOpenStrokes(this.openStrokes - 1));
    this.renderer.requestRedraw();
    this.onCursor();
  }

  // A CSG tool applied where the ray under (x, y) meets the surface.
  async click(x, y, modifier = null) {
    if (!this.editable) return;
    const s = this.controls.settings;
    const { origin, direction } = this.#ray(x, y);
    const op = { tool: toolWithModifier(s.tool, modifier), shape: s.shape, radius: s.radius, blend: round(s.blend * s.radius), ray: { origin, direction } };
    try {
      const result = await this.session.applyTool(op);
      if (result.hit === null) this.messages.notice("The click missed the surface: nothing changed.");
    } catch {
      // the session's "error" event has shown it
    }
  }

  // F+drag (ui/brush-drag.js): sideways scales the radius, up and down the strength (blend
  // for CSG tools); (dx, dy) is the whole drag since brushStart().
  brushStart() {
    this.brushDragging = new BrushDrag(this.controls.settings.radius, this.controls.secondValue);
  }

  brushDrag(dx, dy) {
    if (!this.brushDragging) this.brushStart();
    const { radius, second } = this.brushDragging.at(dx, dy);
    this.controls.setRadius(radius);
    this.controls.setStrength(second);
  }

  // The canvas's data-strokes attribute says how many strokes are still on the wire.
  #setOpenStrokes(n) {
    this.openStrokes = n;
    this.renderer.canvas.dataset.strokes = String(n);
  }

  // The brush cursor in the tool's colour (math/brush-ghost.js: ring and strength ring for
  // brushes, the shape's ghost for CSG tools), fainter rings at the mirrored dabs, and the size
  // readout beside the pointer.
  #updateCursor() {
    const stroke = this.stroke;
    const tool = stroke ? toolById(stroke.tool) : this.controls.tool;
    const cursor = { rings: [], segments: [], color: tool.color };
    const hit = this.hit;
    const readout = this.renderer.canvas.ownerDocument.getElementById("brush-readout");
    if (hit && this.editable) {
      const s = this.controls.settings;
      const perPixel = (2 * hit.t * Math.tan(this.camera.fovY / 2)) / Math.max(1, this.renderer.canvas.clientHeight);
      const width = LINE_PIXELS * perPixel;
      const warp = stroke && stroke.warp;
      const plane = stroke && stroke.sender.plane;
      let ghost;
      if (warp)
        ghost = warpGhost({ name: tool.id, dabs: tool.warp }, { anchor: warp.drag.anchor, anchorNormal: warp.anchorNormal, point: warp.drag.point, path: warp.drag.path, direction: warp.direction, viewNormal: warp.drag.viewNormal }, s.radius);
      else if (tool.warp) ghost = warpGhost({ name: tool.id, dabs: tool.warp }, { anchor: hit.point, anchorNormal: hit.normal, point: null }, s.radius);
      else ghost = brushGhost({ kind: tool.kind, shape: s.shape, strength: s.strength }, hit.point, hit.normal, s.radius);
      if (plane) {
        const disc = planeGhost(plane, s.radius);
        ghost.rings.push(...disc.rings);
      }
      cursor.segments = ghost.segments;
      for (const r of ghost.rings)
        cursor.rings.push({ width, alpha: r.inner ? 0.6 : 0.95, ...r, color: tool.color, primary: !r.inner && tool.kind === "stroke" });
      if (tool.kind === "click") cursor.rings.push({ center: hit.point, normal: hit.normal, radius: 0, width, color: tool.color, alpha: 0.95, primary: true });
      if (tool.kind === "stroke" && !tool.warp)
        for (const image of mirrorImages(hit.point, hit.normal, s.symmetry, this.session.info.size))
          cursor.rings.push({ ...image, radius: s.radius, width, color: tool.color, alpha: 0.45, primary: false });
      const strength = tool.warp ? s.warpStrength : s.strength;
      let size = tool.kind === "click" ? `${s.shape} ${s.radius} vu` : tool.takes.has("strength") ? `${s.radius} vu · ${strength.toFixed(2)}` : `${s.radius} vu`;
      if (warp && warp.drag.point) size = warpReadout(tool.id, warp, s.radius);
      this.#placeReadout(readout, hit.point, `${tool.icon} ${tool.label} · ${size}`);
    } else if (readout) {
      readout.hidden = true;
    }
    this.renderer.cursorShape = cursor;
    this.renderer.requestRedraw();
    this.onCursor();
  }

  // The readout sits just right of and below the brush centre on screen.
  #placeReadout(readout, point, text) {
    if (!readout) return;
    const canvas = this.renderer.canvas;
    this.camera.update(canvas.clientWidth, canvas.clientHeight);
    const [nx, ny, nz] = transformPoint(this.camera.viewProjection, point);
    readout.hidden = !(Math.abs(nx) <= 1 && Math.abs(ny) <= 1 && Math.abs(nz) <= 1);
    readout.textContent = text;
    readout.style.left = `${((nx + 1) / 2) * canvas.clientWidth + 14}px`;
    readout.style.top = `${((1 - ny) / 2) * canvas.clientHeight + 14}px`;
  }
}

// What an open warp stroke does so far, for the readout: how far the anchor moved, the twist's
// angle, the scale's factor, the pinch's factor (PROTOCOL.md, stroke.begin).
function warpReadout(name, { drag, direction }, radius) {
  const s = warpAmount(drag.anchor, drag.point, direction, radius);
  if (name === "twist") return `${Math.round(s * 90)}°`;
  if (name === "scale") return `× ${scaleFactor(s).toFixed(2)}`;
  if (name === "pinch") return `× ${pinchFactor(s).toFixed(2)} towards the middle`;
  return `${distance(drag.anchor, drag.point).toFixed(1)} vu`;
}

// The distinct mirror images of a point and its normal across the domain's middle planes of
// the listed axes, the point itself excluded.
export function mirrorImages(point, normal, axes, size) {
  const images = [{ center: point, normal }];
  for (const axis of axes) {
    const k = "xyz".indexOf(axis);
    for (const img of [...images]) {
      const center = [...img.center];
      const n = [...img.normal];
      center[k] = size[k] - 1 - center[k];
      n[k] = -n[k];
      images.push({ center, normal: n });
    }
  }
  return images.slice(1);
}

function round(v) {
  return Math.round(v * 1e4) / 1e4;
}
