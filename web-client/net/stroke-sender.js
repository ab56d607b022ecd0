// One brush stroke on the wire: stroke.begin, dabs as they happen, stroke.end
// (PROTOCOL.md, "stroke.begin / stroke.dabs / stroke.end").
// Conventions: a dab is {ray: {origin, direction}, pressure} in vu; the server picks the
// surface along each ray on the live volume, so dabs land on the surface as it is when they
// apply, even if this client's splats lag behind. Dabs queue until stroke.begin has answered
// with the stroke's id, and go out at most once per display frame (flush()), in one
// stroke.dabs of up to max_dabs; while MAX_IN_FLIGHT messages are unanswered, dabs wait and
// merge into the next message, so a slow server gets fewer, larger messages rather than a
// growing backlog. Every message has an id: failures come back and are shown.

// The tool registry (protocol/registry/tools.json): which tools take a height, and its bound.
// A relative path, which the browser resolves to the server's /protocol/js/ (ui/tools.js says why).
import { PARAMETERS, TOOLS } from "../../protocol/js/tools.js";

const MAX_IN_FLIGHT = 3;

// How high a stroke of a tool that takes a height (add_blob, remove_blob) stands (stroke.begin
// `height`, vu): strength times HEIGHT_PER_RADIUS of the radius, at most MAX_HEIGHT.
// HEIGHT_PER_RADIUS is the most the server takes (half the radius); at radius 8 and strength 1
// that is a ridge of 4 vu, plain to see on a 128^3 model and nowhere near a tentacle. The cap
// keeps a big brush's message affordable (the server's work grows with the height: a sub-step
// per vu).
export const HEIGHT_PER_RADIUS = PARAMETERS.height.max_per_radius;
export const MAX_HEIGHT = 16;

const TAKES_HEIGHT = new Set(TOOLS.filter((t) => t.params.includes(PARAMETERS.height)).map((t) => t.name));

// The stroke.begin params for the brush settings {tool, radius, strength, symmetry, buildUp}.
// A tool that takes a height gets one, so that the stroke rises (sinks) that far however often
// the pointer passes (the stroke memory, PROTOCOL.md), or with buildUp `accumulate`: every
// message adds again, paint-like. The others (smooth, sharpen) accumulate, since passing again
// is how one smooths more.
export function strokeBeginParams({ tool, radius, strength, symmetry, buildUp = false }) {
  const params = { tool, radius, strength };
  if (symmetry && symmetry.length) params.symmetry = symmetry;
  if (TAKES_HEIGHT.has(tool) && !buildUp) {
    // Rounded down to 1/1000 vu, so that it never exceeds half the radius.
    params.height = Math.max(0.001, Math.floor(1000 * strength * Math.min(HEIGHT_PER_RADIUS * radius, MAX_HEIGHT)) / 1000);
  } else {
    params.accumulate = true;
  }
  return params;
}

export class StrokeSender {
  // session: net/session-client.js; settings: as strokeBeginParams takes them; maxDabs: the
  // server's max_dabs limit.
  constructor(session, settings, maxDabs = 256) {
    this.session = session;
    this.maxDabs = maxDabs;
    this.queue = [];
    this.inFlight = 0;
    this.ended = false;
    this.failed = false;
    this.applied = 0; // dabs the server reported as applied
    this.stroke = null;
    this.params = strokeBeginParams(settings);
    this.begun = session.beginStroke(this.params).then(
      (id) => {
        this.stroke = id;
        this.flush();
      },
      () => {
        this.failed = true;
        this.queue.length = 0;
        this.#maybeEnd();
      },
    );
  }

  add(dab) {
    if (!this.failed && !this.ended) this.queue.push(dab);
  }

  // Sends what is queued, if the stroke has its id and the pipe is not full.
  flush() {
    if (this.stroke === null || this.failed) return;
    while (this.queue.length && this.inFlight < MAX_IN_FLIGHT) {
      const dabs = this.queue.splice(0, this.maxDabs);
      ++this.inFlight;
      this.session.strokeDabs(this.stroke, dabs).then(
        (result) => {
          this.applied += result.applied;
        },
        () => {
          this.failed = true;
          this.queue.length = 0;
        },
      ).finally(() => {
        --this.inFlight;
        this.flush();
        this.#maybeEnd();
      });
    }
    this.#maybeEnd();
  }

  // Ends the stroke once every queued dab is out; resolves when stroke.end has answered.
  end() {
    this.ended = true;
    this.done = new Promise((resolve) => {
      this.resolveDone = resolve;
    });
    this.begun.then(() => this.flush());
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
