// One brush stroke on the wire: stroke.begin, dabs as they happen, stroke.end
// (PROTOCOL.md, "stroke.begin / stroke.dabs / stroke.end").
// Conventions: a dab is {center, pressure?} in vu (or {ray, pressure}). Dabs queue until
// stroke.begin has answered with the stroke's id, and go out at most once per display frame
// (flush()), in one stroke.dabs of up to max_dabs; while MAX_IN_FLIGHT messages are unanswered,
// dabs wait and merge into the next message, so a slow server gets fewer, larger messages rather
// than a growing backlog. Every message has an id: failures come back and are shown.
// Warp strokes (registry kind "warp", math/warp-drag.js) send at most one message per display
// frame, answers included: a warp message costs the server a resampling of the region however
// few its dabs. Those whose dabs are "anchored" (grab, twist, ...: only the stroke's last point
// counts) keep only the newest point waiting, behind the anchor while that has not gone yet,
// and have one message in flight at a time, so the server always works on the pointer's newest
// point. A "path" stroke (snake hook) or a "surface_path" one (pinch path) sends every point,
// as a brush does.
// The server may return the plane a stroke works towards (flatten, contrast: `plane {point,
// normal}`, in stroke.begin's result or in a stroke.dabs result): `plane` holds the first one,
// and onPlane(plane) is called when it arrives.

// The tool registry (protocol/registry/tools.json): which tools take a height, and its bound.
// A relative path, which the browser resolves to the server's /protocol/js/ (ui/tools.js says why).
import { PARAMETERS, TOOLS } from "../../protocol/js/tools.js";

const MAX_IN_FLIGHT = 3;
const MAX_IN_FLIGHT_ANCHORED = 1;

// How high a stroke of a tool that takes a height (add_blob, remove_blob) stands (stroke.begin
// `height`, vu): strength times HEIGHT_PER_RADIUS of the radius, at most MAX_HEIGHT.
// HEIGHT_PER_RADIUS is the most the server takes (half the radius); at radius 8 and strength 1
// that is a ridge of 4 vu, plain to see on a 128^3 model and nowhere near a tentacle. The cap
// keeps a big brush's message affordable (the server's work grows with the height: a sub-step
// per vu).
export const HEIGHT_PER_RADIUS = PARAMETERS.height.max_per_radius;
export const MAX_HEIGHT = 16;

// `tools` below is the registry's list (protocol/js/tools.js TOOLS) unless a test gives its own.
const entry = (tool, tools) => tools.find((t) => t.name === tool);
const takes = (tool, key, tools) => Boolean(entry(tool, tools)?.params.some((p) => p.key === key));
const isWarp = (tool, tools) => entry(tool, tools)?.kind === "warp";

// What a tool's stroke dabs are (the registry's `dabs`): "swept" for brushes, "anchored",
// "path" or "surface_path" for warps.
export function dabsOf(tool, tools = TOOLS) {
  return entry(tool, tools)?.dabs || "swept";
}

// The stroke.begin params for the brush settings {tool, radius, strength, symmetry, buildUp,
// direction}. A tool that takes a height gets one, so that the stroke rises (sinks) that far
// however often the pointer passes (the stroke memory, PROTOCOL.md), or with buildUp
// `accumulate`: every message adds again, paint-like. The other brushes (smooth, sharpen)
// accumulate, since passing again is how one smooths more. A warp takes neither, nor symmetry
// (the server refuses it); those that take a `direction` (twist, scale, pinch) get the one given
// (the camera's screen-right axis: dragging right twists, grows or pinches). The paint tools
// (paint, mask) stand like a height: a pass over the same spot again changes nothing unless
// buildUp; paint takes `color` ([r, g, b]), mask `erase` (the inverting modifier held).
export function strokeBeginParams(
  { tool, radius, strength, symmetry, buildUp = false, direction = null, color = null, erase = false },
  tools = TOOLS,
) {
  const params = { tool, radius };
  if (takes(tool, "strength", tools)) params.strength = strength;
  if (color && takes(tool, "color", tools)) params.color = [...color];
  if (erase && takes(tool, "erase", tools)) params.erase = true;
  if (isWarp(tool, tools)) {
    if (direction && takes(tool, "direction", tools)) params.direction = direction;
    return params;
  }
  if (symmetry && symmetry.length) params.symmetry = symmetry;
  if (entry(tool, tools)?.kind === "paint") {
    if (buildUp) params.accumulate = true;
  } else if (takes(tool, "height", tools) && !buildUp) {
    // Rounded down to 1/1000 vu, so that it never exceeds half the radius.
    params.height = Math.max(0.001, Math.floor(1000 * strength * Math.min(HEIGHT_PER_RADIUS * radius, MAX_HEIGHT)) / 1000);
  } else {
    params.accumulate = true;
  }
  return params;
}

export class StrokeSender {
  // session: net/session-client.js; settings: as strokeBeginParams takes them; maxDabs: the
  // server's max_dabs limit; tools: the registry's list.
  constructor(session, settings, maxDabs = 256, tools = TOOLS) {
    this.session = session;
    this.maxDabs = maxDabs;
    this.queue = [];
    this.inFlight = 0;
    this.ended = false;
    this.failed = false;
    this.applied = 0; // dabs the server reported as applied
    this.sent = 0; // dabs sent
    this.stroke = null;
    this.plane = null;
    this.onPlane = () => {};
    this.params = strokeBeginParams(settings, tools);
    this.coalesce = dabsOf(settings.tool, tools) === "anchored";
    this.perFrame = isWarp(settings.tool, tools); // one message per display frame, answers included
    this.frameOpen = true; // no message has gone since the last display frame
    this.maxInFlight = this.coalesce ? MAX_IN_FLIGHT_ANCHORED : MAX_IN_FLIGHT;
    this.begun = session.beginStroke(this.params).then(
      (result) => {
        this.stroke = result.stroke;
        this.#takePlane(result);
        this.#pump();
      },
      () => {
        this.failed = true;
        this.queue.length = 0;
        this.#maybeEnd();
      },
    );
  }

  add(dab) {
    if (this.failed || this.ended) return;
    // Anchored: the newest point replaces the one waiting; an anchor not sent yet stays first.
    const keep = this.sent ? 0 : 1;
    if (this.coalesce && this.queue.length > keep) this.queue.length = keep;
    this.queue.push(dab);
  }

  // A display frame: sends what is queued, if the stroke has its id and the pipe is not full.
  flush() {
    this.frameOpen = true;
    this.#pump();
  }

  #pump() {
    if (this.stroke === null || this.failed) return;
    while (this.queue.length && this.inFlight < this.maxInFlight && (this.frameOpen || !this.perFrame)) {
      const dabs = this.queue.splice(0, this.maxDabs);
      ++this.inFlight;
      this.sent += dabs.length;
      this.frameOpen = false;
      this.session.strokeDabs(this.stroke, dabs).then(
        (result) => {
          this.applied += result.applied;
          this.#takePlane(result);
        },
        () => {
          this.failed = true;
          this.queue.length = 0;
        },
      ).finally(() => {
        --this.inFlight;
        this.#pump();
        this.#maybeEnd();
      });
    }
    this.#maybeEnd();
  }

  #takePlane(result) {
    const plane = result && result.plane;
    if (this.plane || !plane || !Array.isArray(plane.point) || !Array.isArray(plane.normal)) return;
    this.plane = { point: plane.point, normal: plane.normal };
    this.onPlane(this.plane);
  }

  // Ends the stroke once every queued dab is out; resolves when stroke.end has answered.
  end() {
    this.ended = true;
    this.perFrame = false; // no display frame flushes a stroke that has ended
    this.frameOpen = true;
    this.done = new Promise((resolve) => {
      this.resolveDone = resolve;
    });
    this.begun.then(() => this.#pump());
    return this.done;
  }

  #maybeEnd() {
    if (!this.ended || this.sentEnd || this.queue.length || this.inFlight) return;
    if (this.stroke === null && !this.failed) return;
    this.sentEnd = true;
    if (this.stroke === null) return this.resolveDone(null);
    this.session.endStroke(this.stroke).then(this.resolveDone, () => this.resolveDone(null));
  }
}
