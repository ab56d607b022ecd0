// The one offline banner: while an open session's connection is down it says so once, with the
// reason and when the next attempt comes, and that sculpting waits until the session is back
// (the pointer handling sculpts nothing and does not turn the camera meanwhile). It replaces a
// message per reconnection attempt.

export class OfflineBanner {
  constructor(doc) {
    this.el = doc.getElementById("offline");
    this.text = doc.getElementById("offline-text");
  }

  // detail: the session's "connection" event.
  show({ state, because, attempt, delayMs }) {
    const down = state === "reconnecting";
    this.el.hidden = !down;
    if (!down) return;
    const why = because ? `The connection to the server dropped (${because}).` : "The connection to the server dropped.";
    const next = delayMs ? `Reconnecting in ${(delayMs / 1000).toFixed(1)} s (attempt ${attempt})` : `Reconnecting (attempt ${attempt})…`;
    this.text.textContent = `${why} ${next}. Sculpting is paused until the session is back.`;
  }
}
