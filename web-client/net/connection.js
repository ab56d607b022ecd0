// One WebSocket to the server: JSON-RPC requests with their answers, binary frames, pushes.
// Conventions: text frames are JSON-RPC 2.0 and binary frames carry the 24-byte header of
// protocol/js/frames.js (PROTOCOL.md, "Transport" and "Binary frames"). A binary frame that
// answers a request (its header's request id) arrives before that request's response, so the
// response resolves with both. Frames with request id 0 are pushes. `opened` resolves once
// the socket is open, or rejects with ConnectionRefused.
// Events (EventTarget, detail in event.detail):
//   "open"; "close" {code, reason, intentional}; "notification" {method, params};
//   "push" {header, payload}; "rtt" {method, ms}; "protocol-error" {message}: something the
//   server must not send (kept apart from RpcErrors, which are answers).
// Ownership: a Connection is used once; reconnecting makes a new one (net/session-client.js).

import { decodeFrame, encodeFrame } from "/protocol/js/frames.js";
import { MessageKind, RequestBuilder, classifyMessage } from "/protocol/js/rpc.js";
import { ConnectionLost, ConnectionRefused, RpcError } from "./rpc-error.js";

export class Connection extends EventTarget {
  #socket;
  #builder = new RequestBuilder();
  #pending = new Map(); // id -> {method, resolve, reject, sentAt, frame}
  #intentional = false;

  constructor(url, { WebSocketImpl = WebSocket } = {}) {
    super();
    this.url = url;
    this.#socket = new WebSocketImpl(url);
    this.#socket.binaryType = "arraybuffer";
    this.opened = new Promise((resolve, reject) => {
      this.#socket.addEventListener("open", () => {
        resolve();
        this.#emit("open");
      });
      this.#socket.addEventListener("close", (e) => {
        reject(new ConnectionRefused(url, e.code));
        this.#closed(e.code, e.reason);
      });
    });
    this.opened.catch(() => {});
    this.#socket.addEventListener("message", (e) => this.#receive(e.data));
  }

  get isOpen() {
    return this.#socket.readyState === 1;
  }

  // Bytes queued in the socket, not yet handed to the network.
  get bufferedAmount() {
    return this.#socket.bufferedAmount;
  }

  // Sends a request; resolves with {result, frame} (frame: {header, payload} when the method is
  // answered by a binary frame, else null) or rejects with RpcError / ConnectionLost.
  // `afterSend(id)` runs right after the text is sent, before any other message: volume.load
  // sends its upload there.
  request(method, params, afterSend) {
    if (!this.isOpen) return Promise.reject(new ConnectionLost(method));
    const { id, text } = this.#builder.request(method, params);
    return new Promise((resolve, reject) => {
      this.#pending.set(id, { method, params, resolve, reject, sentAt: performance.now(), frame: null });
      this.#socket.send(text);
      if (afterSend) afterSend(id);
    });
  }

  // A client notification: carried out by the server, never answered.
  notify(method, params) {
    if (this.isOpen) this.#socket.send(this.#builder.notification(method, params));
  }

  // An upload frame (kind 9) answering request `requestId`.
  sendUpload(kind, requestId, payload) {
    this.#socket.send(encodeFrame(kind, requestId, 0, payload));
  }

  // Closes on purpose: no reconnect follows.
  close(code = 1000, reason = "") {
    this.#intentional = true;
    if (this.#socket.readyState <= 1) this.#socket.close(code, reason);
  }

  #emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, { detail }));
  }

  #closed(code, reason) {
    for (const [, p] of this.#pending) p.reject(new ConnectionLost(p.method));
    this.#pending.clear();
    this.#emit("close", { code, reason, intentional: this.#intentional });
  }

  #receive(data) {
    if (typeof data === "string") return this.#receiveText(data);
    const frame = decodeFrame(data);
    if (!frame.ok) return this.#emit("protocol-error", { message: `binary frame refused: ${frame.message}` });
    const id = frame.header.requestId;
    if (id === 0) return this.#emit("push", frame);
    const pending = this.#pending.get(id);
    if (pending) pending.frame = frame;
    else this.#emit("protocol-error", { message: `a binary frame answers request ${id}, which is not pending` });
  }

  #receiveText(text) {
    const m = classifyMessage(text);
    if (m.kind === MessageKind.Notification) return this.#emit("notification", { method: m.method, params: m.params });
    if (m.kind === MessageKind.Invalid) return this.#emit("protocol-error", { message: `message refused: ${m.reason}` });
    const pending = this.#pending.get(m.id);
    if (!pending) {
      if (m.kind === MessageKind.Error)
        return this.#emit("protocol-error", { message: `error ${m.error.code} without a request: ${m.error.message}` });
      return this.#emit("protocol-error", { message: `a response to request ${m.id}, which is not pending` });
    }
    this.#pending.delete(m.id);
    this.#emit("rtt", { method: pending.method, ms: performance.now() - pending.sentAt });
    if (m.kind === MessageKind.Error) pending.reject(new RpcError(pending.method, m.error, pending.params));
    else pending.resolve({ result: m.result, frame: pending.frame });
  }
}
