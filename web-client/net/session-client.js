// The session as this client sees it: joining (create, join, rejoin after a drop), the state
// every client shares (revision, digest, undo/redo, who is connected) and one method per
// request of PROTOCOL.md.
// Conventions: revisions are Numbers (they fit in 53 bits, PROTOCOL.md "Revisions"), the
// digest is 16 hex digits. Streaming: create and join ask for `splats` (a full buffer, then
// deltas after every change); so does a rejoin after a dropped connection, whose full buffer
// resyncs the client (the frame view asks for its mode again on "joined" with rejoined). The
// buffers are of splat format version 2 (`splats: 2`): points carry colour and mask.
// Events (EventTarget, detail in event.detail):
//   "connection" {state: connecting|connected|reconnecting|closed, because, attempt?, delayMs?}:
//   `because` says why the connection of an open session dropped ("code 1006"), null while it holds
//   "joined" {info, rejoined}; "state" {revision, digest, canUndo, canRedo, cause?, by?};
//   "clients" {clients}; "splats" {full, revision, payload}; "frame" {kind, revision, payload};
//   "presence" (params of a `presence` notification: another client's brush and camera, or
//   {client, gone});
//   "rtt" {method, ms}; "error" {error, context}: every error a request got (RpcError) and
//   every protocol problem, for the person to read; "lost" {error}: the session cannot be
//   rejoined (it no longer exists, or the token no longer opens it).

import { FrameKind } from "/protocol/js/frames.js";
import { PROTOCOL_VERSION, RpcErrorCode } from "/protocol/js/rpc.js";
import { SPLAT_FORMAT_VERSION } from "/protocol/js/splats.js";
import { Connection } from "./connection.js";
import { RpcError } from "./rpc-error.js";
import { newSessionId, socketUrl } from "./session-link.js";
import { undoScope } from "./undo-scope.js";

const RECONNECT_FIRST_MS = 500;
const RECONNECT_MAX_MS = 8000;
const CREATE_ATTEMPTS = 3; // fresh ids to try when the proposed one exists (-32014)
// Presence is not sent while this much is waiting in the socket: it would only queue behind
// strokes, and the next one replaces it anyway.
const PRESENCE_BACKLOG_BYTES = 64 * 1024;

export class SessionClient extends EventTarget {
  #connection = null;
  #reconnectTimer = 0;
  #attempt = 0;
  #credentials = null; // {session, token} to rejoin with

  constructor(pageUrl) {
    super();
    this.pageUrl = pageUrl;
    this.info = null; // result of create/join: session, client, size, limits, read_only, tokens
    this.revision = 0;
    this.digest = "";
    this.canUndo = false;
    this.canRedo = false;
    this.clients = [];
    this.connectionState = "closed";
    this.lostBecause = null; // why the open session's connection dropped, until it is back
  }

  get connected() {
    return this.connectionState === "connected";
  }

  get readOnly() {
    return Boolean(this.info && this.info.read_only);
  }

  // Creates a session of size^3 voxels starting as `solid`, proposing a fresh id. `name`: this
  // client's display name (PROTOCOL.md "Presence"); empty or left out, the server names it.
  async create({ size, solid, name }) {
    for (let attempt = 1; ; ++attempt) {
      const session = newSessionId();
      try {
        await this.#connect(session);
        const { result } = await this.#connection.request("session.create", {
          size: [size, size, size],
          solid,
          session,
          protocol: PROTOCOL_VERSION.major,
          view: "splats",
          splats: SPLAT_FORMAT_VERSION, // colour and mask (splat format version 2)
          ...nameParam(name),
        });
        this.#credentials = { session: result.session, token: result.token, name };
        this.#joined(result, false);
        return result;
      } catch (e) {
        this.#drop();
        if (!(e instanceof RpcError && e.code === RpcErrorCode.SessionExists) || attempt >= CREATE_ATTEMPTS) {
          this.#setConnection("closed");
          throw e;
        }
      }
    }
  }

  // Joins an existing session with an edit or a view token (`name` as for create).
  async join({ session, token, name }) {
    try {
      await this.#connect(session);
      const { result } = await this.#connection.request("session.join", {
        session,
        token,
        protocol: PROTOCOL_VERSION.major,
        view: "splats",
        splats: SPLAT_FORMAT_VERSION,
        ...nameParam(name),
      });
      this.#credentials = { session, token, name };
      this.#joined(result, false);
      return result;
    } catch (e) {
      this.#drop();
      this.#setConnection("closed");
      throw e;
    }
  }

  // Leaves for good: no reconnect.
  leave() {
    clearTimeout(this.#reconnectTimer);
    this.#credentials = null;
    if (this.#connection && this.#connection.isOpen) this.#connection.request("session.leave", {}).catch(() => {});
    this.#drop();
    this.#setConnection("closed");
  }

  // Sends a request and reports its failure as an "error" event too (then rethrows).
  async request(method, params, afterSend) {
    if (!this.#connection) throw new RpcError(method, { code: RpcErrorCode.NotInSession, message: "not connected to a session" });
    try {
      return await this.#connection.request(method, params, afterSend);
    } catch (e) {
      // Lets an error's text name this page's own client as "you" and the others by their
      // display names (plain-errors.js).
      if (e instanceof RpcError && this.info) {
        e.self = this.info.client;
        e.names = new Map(this.clients.map((c) => [c.client, c.name]));
      }
      this.#emit("error", { error: e, context: method });
      throw e;
    }
  }

  // Bytes waiting in the socket: lets senders of frequent messages hold back.
  get bufferedAmount() {
    return this.#connection ? this.#connection.bufferedAmount : 0;
  }

  // This client's presence (PROTOCOL.md "Presence"), a notification: false when it was not sent
  // (offline, or the socket still holds PRESENCE_BACKLOG_BYTES).
  sendPresence(params) {
    if (!this.connected || !this.#connection || !this.info || this.bufferedAmount > PRESENCE_BACKLOG_BYTES) return false;
    this.#connection.notify("presence", params);
    return true;
  }

  // --- edits ------------------------------------------------------------------------------

  async applyTool(op) {
    const { result } = await this.request("tool.apply", op);
    this.#advance(result.revision);
    return result;
  }

  // op.cancel: stops this connection's long request (which then fails with -32016 and changes
  // nothing); true when one was running.
  async cancel() {
    const { result } = await this.request("op.cancel", {});
    return result.cancelled;
  }

  async morph(kind, radius) {
    const { result } = await this.request("volume.morph", { kind, radius });
    this.#advance(result.revision);
    return result;
  }

  // The scope undo and redo use now (net/undo-scope.js): "mine" while another editor is in.
  get undoScope() {
    return undoScope(this.clients, this.info ? this.info.client : null);
  }

  async undo(scope = this.undoScope) {
    const { result } = await this.request("history.undo", { scope });
    this.#history(result);
    return result;
  }

  async redo(scope = this.undoScope) {
    const { result } = await this.request("history.redo", { scope });
    this.#history(result);
    return result;
  }

  // {revision, steps, more}: the session's newest steps (history.list gives one page of at most
  // `limit`, newest first), here oldest first, then the undone ones in redo order, as the
  // timeline lists them; more: older steps were left out.
  async historyList(limit = 1000) {
    const { result } = await this.request("history.list", { limit });
    return { ...result, steps: [...result.steps].reverse() };
  }

  // A new session from this one's volume at `revision` (the current one when left out): this
  // client leaves the old session and is the fork's only client, with its edit token; a full
  // splat buffer follows as after a join, and a later rejoin goes to the fork.
  async fork(revision) {
    const { result } = await this.request("session.fork", revision === undefined ? {} : { revision });
    this.#credentials = { session: result.session, token: result.token, name: this.#credentials && this.#credentials.name };
    this.info = null;
    this.#joined(result, false);
    return result;
  }

  // Resolves with stroke.begin's result: {stroke} (and, for flatten and contrast, maybe `plane`).
  async beginStroke(params) {
    const { result } = await this.request("stroke.begin", params);
    return result;
  }

  async strokeDabs(stroke, dabs) {
    const { result } = await this.request("stroke.dabs", { stroke, dabs });
    this.#advance(result.revision);
    return result;
  }

  async endStroke(stroke) {
    const { result } = await this.request("stroke.end", { stroke });
    this.#history(result);
    return result;
  }

  // --- views and data ------------------------------------------------------------------

  // mode: "splats" | "frames" (with camera, width, height) | "none".
  async setView(params) {
    const { result } = await this.request("view.set", params);
    return result;
  }

  // {result, frame}: frame.payload is the image file.
  renderFrame(params) {
    return this.request("render.frame", params);
  }

  // The whole splat buffer now: {revision, payload} (a kind-1 payload).
  async splatsSnapshot() {
    const { result, frame } = await this.request("splats.get", {});
    return { revision: result.revision, payload: frame.payload };
  }

  exportMesh(format) {
    return this.request("mesh.export", { format });
  }

  // format: "mzv" (the default) or "vdb" (servers with OpenVDB, limits.volume_formats).
  saveVolume(format = "mzv") {
    return this.request("volume.save", format === "mzv" ? {} : { format });
  }

  async loadVolume(bytes, format = "mzv") {
    const params = format === "mzv" ? { bytes: bytes.byteLength } : { bytes: bytes.byteLength, format };
    const { result } = await this.request("volume.load", params, (id) => this.#connection.sendUpload(FrameKind.VolumeUpload, id, bytes));
    this.#history(result);
    if (result.digest) this.digest = result.digest;
    this.#emitState();
    return result;
  }

  async stats() {
    const { result } = await this.request("session.stats", {});
    this.digest = result.digest;
    this.canUndo = result.can_undo;
    this.canRedo = result.can_redo;
    this.#advance(result.revision);
    this.#setClients(result.clients);
    return result;
  }

  // --- connection -----------------------------------------------------------------------

  async #connect(session) {
    this.#drop();
    this.#setConnection(this.#attempt > 0 ? "reconnecting" : "connecting", { attempt: this.#attempt });
    const c = new Connection(socketUrl(this.pageUrl, session));
    this.#connection = c;
    c.addEventListener("notification", (e) => this.#notification(e.detail));
    c.addEventListener("push", (e) => this.#push(e.detail));
    c.addEventListener("rtt", (e) => this.#emit("rtt", e.detail));
    c.addEventListener("protocol-error", (e) => this.#emit("error", { error: new Error(e.detail.message), context: "protocol" }));
    c.addEventListener("close", (e) => this.#closed(c, e.detail));
    await c.opened;
  }

  #drop() {
    if (!this.#connection) return;
    this.#connection.close();
    this.#connection = null;
  }

  #closed(connection, { code, reason, intentional }) {
    if (connection !== this.#connection || intentional) return;
    this.#connection = null;
    if (!this.#credentials) return this.#setConnection("closed");
    // Said once, by the connection state (the app's offline banner), not as an error per attempt.
    if (!this.lostBecause) this.lostBecause = `code ${code}${reason ? `: ${reason}` : ""}`;
    this.#scheduleRejoin();
  }

  #scheduleRejoin() {
    clearTimeout(this.#reconnectTimer);
    const delayMs = Math.min(RECONNECT_MAX_MS, RECONNECT_FIRST_MS * 2 ** this.#attempt) * (0.8 + 0.4 * Math.random());
    ++this.#attempt;
    this.#setConnection("reconnecting", { attempt: this.#attempt, delayMs });
    this.#reconnectTimer = setTimeout(() => this.#rejoin(), delayMs);
  }

  async #rejoin() {
    const creds = this.#credentials;
    if (!creds) return;
    try {
      await this.#connect(creds.session);
      const { result } = await this.#connection.request("session.join", {
        session: creds.session,
        token: creds.token,
        protocol: PROTOCOL_VERSION.major,
        view: "splats",
        splats: SPLAT_FORMAT_VERSION,
        ...nameParam(creds.name),
      });
      this.#joined(result, true);
    } catch (e) {
      const fatal = e instanceof RpcError && [RpcErrorCode.NoSuchSession, RpcErrorCode.BadToken].includes(e.code);
      if (fatal) {
        this.#credentials = null;
        this.#drop();
        this.#setConnection("closed");
        this.#emit("lost", { error: e });
      } else if (this.#credentials) {
        this.#drop();
        this.#scheduleRejoin();
      }
    }
  }

  #joined(result, rejoined) {
    this.#attempt = 0;
    this.lostBecause = null;
    this.info = { ...(this.info || {}), ...result };
    this.revision = result.revision;
    this.digest = result.digest;
    this.canUndo = result.can_undo;
    this.canRedo = result.can_redo;
    this.#setConnection("connected");
    this.#setClients(result.clients || []);
    this.#emit("joined", { info: this.info, rejoined });
    this.#emitState();
  }

  #setConnection(state, extra = {}) {
    this.connectionState = state;
    this.#emit("connection", { state, because: this.lostBecause, ...extra });
  }

  #setClients(clients) {
    this.clients = clients;
    this.#emit("clients", { clients });
  }

  // --- what the server tells ----------------------------------------------------------------

  #notification({ method, params }) {
    if (method === "session.changed") {
      this.revision = Math.max(this.revision, params.revision);
      this.digest = params.digest;
      this.canUndo = params.can_undo;
      this.canRedo = params.can_redo;
      this.#emitState({ cause: params.cause, by: params.by, roi: params.roi });
    } else if (method === "session.clients") {
      this.#setClients(params.clients);
    } else if (method === "op.progress") {
      this.#emit("progress", params);
    } else if (method === "presence") {
      this.#emit("presence", params);
    }
  }

  #push({ header, payload }) {
    const revision = Number(header.revision);
    switch (header.kind) {
      case FrameKind.SplatsFull:
      case FrameKind.SplatsDelta:
        this.#emit("splats", { full: header.kind === FrameKind.SplatsFull, revision, payload });
        break;
      case FrameKind.FrameJpeg:
      case FrameKind.FramePng:
        this.#emit("frame", { kind: header.kind, revision, payload });
        break;
      default:
        this.#emit("error", { error: new Error(`unexpected pushed frame of kind ${header.kind}`), context: "protocol" });
    }
  }

  #advance(revision) {
    if (typeof revision === "number" && revision > this.revision) {
      this.revision = revision;
      this.#emitState();
    }
  }

  #history(result) {
    this.canUndo = result.can_undo;
    this.canRedo = result.can_redo;
    this.revision = Math.max(this.revision, result.revision);
    this.#emitState();
  }

  #emitState(extra = {}) {
    this.#emit("state", {
      revision: this.revision,
      digest: this.digest,
      canUndo: this.canUndo,
      canRedo: this.canRedo,
      ...extra,
    });
  }

  #emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, { detail }));
  }
}

// The `name` param of create and join: left out when there is none to give.
function nameParam(name) {
  const trimmed = typeof name === "string" ? name.trim() : "";
  return trimmed ? { name: trimmed } : {};
}
