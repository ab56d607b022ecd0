// This page's presence on the wire (PROTOCOL.md "Presence"): its brush under the pointer and
// its camera, sent as `presence` notifications at pointer rate but at most once per
// PRESENCE_INTERVAL_MS, newest only. Callers poke() whenever something presence shows may have
// changed (the pointer moved, the camera turned, a stroke began or ended); the message itself
// is composed when it goes out, from the state as it is then, so whatever changed between two
// sends is never queued, only the latest is sent. An unchanged presence is not sent again,
// except once every PRESENCE_REFRESH_MS so that the others can tell a resting pointer from a
// page that has gone silent (they hide a ring after STALE_MS without word).
// Conventions: times in ms of `now()`; the clock and timers are injectable for the unit tests,
// and so are the protocol's presenceParams and PRESENCE_INTERVAL_MS (protocol/js/presence.js,
// which the app imports from the server's /protocol/js/), so that this module imports nothing.

export const PRESENCE_REFRESH_MS = 2000;
// Without a presence for this long, a client's brush ring is hidden (its camera stays
// followable): three missed refreshes.
export const STALE_MS = 3 * PRESENCE_REFRESH_MS;

// Calls `fire()` at most once per `intervalMs`: a poke within the interval after the last fire
// arms one timer for the rest of it (later pokes join it), a poke after it fires at once.
export class Throttle {
  #last = -Infinity;
  #timer = null;

  constructor(intervalMs, fire, { now = () => performance.now(), setTimer = (f, ms) => setTimeout(f, ms), clearTimer = (t) => clearTimeout(t) } = {}) {
    Object.assign(this, { intervalMs, fire, now, setTimer, clearTimer });
  }

  poke() {
    if (this.#timer !== null) return;
    const wait = this.#last + this.intervalMs - this.now();
    if (wait <= 0) return this.#fire();
    this.#timer = this.setTimer(() => {
      this.#timer = null;
      this.#fire();
    }, wait);
  }

  // Drops an armed timer (leaving the session).
  cancel() {
    if (this.#timer !== null) this.clearTimer(this.#timer);
    this.#timer = null;
  }

  #fire() {
    this.#last = this.now();
    this.fire();
  }
}

// The params of this page's presence: the brush when the pointer is on the model and the page
// may sculpt (a view client has none: the server would drop it), and the camera. A camera the
// protocol refuses (an eye farther than 1e5 vu, possible in the telephoto view of a 512³ grid)
// is left out rather than sent to be refused.
// state: {brush: {tool, radius, point, normal, active} | null, camera: {eye, target, up, fov},
// readOnly}; check: protocol/js presenceParams.
export function composePresence({ brush, camera, readOnly }, check) {
  const params = {};
  if (brush && !readOnly) params.brush = check({ brush: { ...brush, radius: Math.min(1024, Math.max(0.5, brush.radius)) } }).brush;
  try {
    params.camera = check({ camera }).camera;
  } catch (e) {
    if (!(e instanceof RangeError)) throw e;
  }
  return params;
}

// Sends `compose()`'s params through `send(params)` (the session's notification; false when
// it could not go out), throttled to one per `intervalMs`, skipping a repeat of the last one
// sent until it is due as a refresh.
export class PresenceSender {
  #lastText = "";
  #lastAt = -Infinity;
  #refresh = null;

  constructor({
    compose,
    send,
    intervalMs,
    now = () => performance.now(),
    setTimer = (f, ms) => setTimeout(f, ms),
    clearTimer = (t) => clearTimeout(t),
    setRepeat = (f, ms) => setInterval(f, ms),
    clearRepeat = (t) => clearInterval(t),
  }) {
    Object.assign(this, { compose, send, now, clearRepeat });
    this.throttle = new Throttle(intervalMs, () => this.#send(), { now, setTimer, clearTimer });
    this.#refresh = setRepeat(() => this.throttle.poke(), PRESENCE_REFRESH_MS);
    this.refreshAfterMs = PRESENCE_REFRESH_MS - intervalMs; // timer jitter must not skip a refresh
    this.sent = 0;
  }

  poke() {
    this.throttle.poke();
  }

  // The next presence goes out even if unchanged (a client joined and knows nothing of us yet).
  resend() {
    this.#lastText = "";
    this.throttle.poke();
  }

  stop() {
    this.throttle.cancel();
    this.clearRepeat(this.#refresh);
  }

  #send() {
    const params = this.compose();
    if (!params) return;
    const text = JSON.stringify(params);
    const now = this.now();
    if (text === this.#lastText && now - this.#lastAt < this.refreshAfterMs) return;
    if (!this.send(params)) return;
    this.#lastText = text;
    this.#lastAt = now;
    ++this.sent;
  }
}
