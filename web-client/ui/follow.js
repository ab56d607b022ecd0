// Following another client's camera (issue 14): once a name in the people list is clicked,
// every camera that client's presence carries becomes this page's camera, until this page's
// person moves the camera themselves (orbit, pan, zoom, a preset, focus), clicks the name
// again, or the leader leaves. Works the same for view clients, who send cameras too.
// Pure state, no DOM: the app applies the cameras and the people list shows the state.
// Conventions: clients by their session id; `onChange({leader, following, reason})` after
// every change of state, `reason` why following last stopped ("you moved the camera",
// "they left", "stopped") or null.

export class Follow {
  constructor(onChange = () => {}) {
    this.onChange = onChange;
    this.leader = null; // the client followed, or null
    this.reason = null;
  }

  get following() {
    return this.leader !== null;
  }

  // Follows `client`; a second click on the leader stops. Returns the leader's newest camera
  // to take at once (from `cameraOf(client)`), or null.
  toggle(client, cameraOf = () => null) {
    if (this.leader === client) {
      this.#stop("stopped");
      return null;
    }
    this.leader = client;
    this.reason = null;
    this.#changed();
    return cameraOf(client) || null;
  }

  // A presence arrived: the camera to take now, or null (not the leader's, or it has none).
  cameraFrom(presence) {
    return this.leader !== null && presence.client === this.leader && presence.camera ? presence.camera : null;
  }

  // This page's person moved the camera: following stops (true when it was on).
  userMoved() {
    if (this.leader === null) return false;
    this.#stop("you moved the camera");
    return true;
  }

  // A client left (presence gone, or missing from session.clients).
  gone(client) {
    if (this.leader === client) this.#stop("they left");
  }

  // The reason following stopped has been told long enough.
  forgetReason() {
    if (this.leader === null) this.reason = null;
  }

  // Leaving the session.
  reset() {
    if (this.leader !== null) this.#stop(null);
  }

  #stop(reason) {
    this.leader = null;
    this.reason = reason;
    this.#changed();
  }

  #changed() {
    this.onChange({ leader: this.leader, following: this.following, reason: this.reason });
  }
}
