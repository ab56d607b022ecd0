// Keeps the client's splats current while the frame view shows the server's pictures. In that
// view the session streams frames, not splat deltas, yet the brush ring, picking and dab
// spacing work on the client's splats; without this they would stay at the revision the frame
// view started from, and a drag over new geometry would orbit instead of sculpting. After
// each change of the session it fetches the whole splat buffer (splats.get), at most one
// request in flight and one every MIN_INTERVAL_MS, and always ends at the newest revision.

export const MIN_INTERVAL_MS = 250;

export class PickSync {
  // session: net/session-client.js; held(): the revision of the splats the client holds;
  // apply({full, revision, payload}): as a pushed splat buffer.
  constructor(session, held, apply, minIntervalMs = MIN_INTERVAL_MS) {
    this.session = session;
    this.held = held;
    this.apply = apply;
    this.minIntervalMs = minIntervalMs;
    this.active = false;
    this.inFlight = false;
    this.lastAt = -Infinity;
    this.timer = 0;
  }

  // The frame view started (true) or ended (false).
  setActive(active) {
    this.active = active;
    if (!active) clearTimeout(this.timer);
    else this.changed();
  }

  // The session's revision moved (a "state" event).
  changed() {
    if (!this.active || this.inFlight || this.session.revision <= this.held()) return;
    const wait = this.lastAt + this.minIntervalMs - performance.now();
    clearTimeout(this.timer);
    if (wait > 0) this.timer = setTimeout(() => this.changed(), wait);
    else this.#fetch();
  }

  async #fetch() {
    this.inFlight = true;
    this.lastAt = performance.now();
    try {
      const { revision, payload } = await this.session.splatsSnapshot();
      if (this.active && revision > this.held()) this.apply({ full: true, revision, payload });
    } catch {
      // Reported by the session's "error" event; the next change of the session tries again.
      this.inFlight = false;
      return;
    }
    this.inFlight = false;
    this.changed();
  }
}
