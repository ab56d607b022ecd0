// Errors of requests: what the server answered (RpcError, with the code of PROTOCOL.md's
// table), that the answer cannot come because the connection ended (ConnectionLost), or that
// the WebSocket never opened (ConnectionRefused).
// Callers branch on `code` and `data`; `message` is the server's sentence for a person.

import { rpcErrorName, undoConflictOf } from "/protocol/js/rpc.js";

export class RpcError extends Error {
  // params: the request's own (what a refusal's text may depend on, e.g. volume.load's format).
  constructor(method, { code, message, data }, params = {}) {
    super(message);
    this.name = "RpcError";
    this.method = method;
    this.params = params;
    this.code = code;
    this.data = data;
    this.conflict = undoConflictOf({ code, data }); // {client, revision, step} for -32017, else null
    this.self = null; // this page's client id, when the session client knows it
  }

  // "InvalidParams" for -32602; the number itself for a code this client does not know.
  get codeName() {
    return rpcErrorName(this.code) || String(this.code);
  }
}

export class ConnectionLost extends Error {
  constructor(method) {
    super(`the connection closed before the answer to ${method} arrived`);
    this.name = "ConnectionLost";
    this.method = method;
  }
}

export class ConnectionRefused extends Error {
  constructor(url, code) {
    super(`the server did not accept a WebSocket at ${url} (close code ${code})`);
    this.name = "ConnectionRefused";
  }
}
