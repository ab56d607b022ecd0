// Errors in plain language: what a person is told when a request fails, with the protocol's
// own words (method, message, code) kept as the detail for whoever wants them.
// plainError(error) -> {text, detail}; detail is "" when the plain text says everything.

import { undoConflictText } from "./undo-scope.js";

// What went wrong, by the code's name in PROTOCOL.md's table (RpcError.codeName); a function
// receives the RpcError for texts that depend on the method or the server's message.
const TEXTS = {
  ParseError: "The server could not read a message from this page. Reloading the page usually helps.",
  InvalidRequest: "The server could not read a message from this page. Reloading the page usually helps.",
  UnknownMethod: "This page asked for something the server does not offer: the page and the server are of different versions. Reload the page.",
  InvalidParams: (e) => (e.method === "volume.load" ? refusedVolume(e) : "The server refused a value this page sent."),
  InternalError: "The server could not store the change, so nothing changed. Try again in a moment.",
  NoSuchSession: "This session does not exist on the server (any more).",
  BadToken: "The link's token does not open this session: check that the whole link was copied.",
  SessionFull: "This session is full: too many people are in it right now.",
  LimitExceeded: (e) => `That goes beyond what this server allows: ${sentence(e.message)}`,
  Busy: "The server is busy: slow down for a moment.",
  EngineRefused: (e) => (e.method === "volume.load" ? refusedVolume(e) : `The sculpting engine refused it: ${sentence(e.message)}`),
  ReadOnlyToken: "You joined with a view link: you can watch, but not sculpt.",
  UnsupportedProtocolVersion: "The server speaks a newer version of the protocol: reload the page.",
  NotInSession: "This page is not in a session: open one from the start screen.",
  AlreadyInSession: "This page is already in a session.",
  NoSuchStroke: "The stroke was interrupted (the connection dropped or the server restarted): start it again.",
  NothingToUndoRedo: (e) => (e.method === "history.redo" ? "There is nothing to redo." : "There is nothing to undo."),
  UploadMissing: "The file did not reach the server: load it again.",
  SessionExists: "A session with this id exists already.",
  SessionHeldElsewhere: "This session is open on another server; reconnecting there may take a moment.",
  Cancelled: "The operation was cancelled; the session is unchanged.",
  // e.conflict: net/rpc-error.js reads data {client, revision, step} with protocol/js undoConflictOf.
  UndoConflict: (e) =>
    e.conflict
      ? undoConflictText(e.conflict, e.method === "history.redo", e.self, e.names)
      : "A later step changed the same place as yours, so it cannot be taken back alone; nothing changed.",
};

export function plainError(error) {
  if (error && error.name === "RpcError") {
    const entry = Object.hasOwn(TEXTS, error.codeName) ? TEXTS[error.codeName] : undefined;
    const text = typeof entry === "function" ? entry(error) : entry || `The server refused it: ${sentence(error.message)}`;
    const field = error.data && error.data.field ? ` (field "${error.data.field}")` : "";
    return { text, detail: `${error.method}: ${error.message}${field} [${error.code} ${error.codeName}]` };
  }
  if (error && error.name === "ConnectionLost") return { text: "The connection dropped before the server answered.", detail: error.message };
  if (error && error.name === "ConnectionRefused") return { text: "The server could not be reached.", detail: error.message };
  return { text: error && error.message ? error.message : String(error), detail: "" };
}

// A refused volume.load, named by the format the file was sent as (the request's params.format;
// "mzv" when absent). The text is made when the error is first shown, as the request fails.
function refusedVolume(e) {
  const what = e.params && e.params.format === "vdb" ? "an OpenVDB level set (.vdb)" : "a Marzipan volume (.mzv)";
  return `This file is not ${what} that fits this session.`;
}

// A server message as the end of a sentence: one final period.
function sentence(message) {
  return `${String(message).replace(/[.\s]+$/, "")}.`;
}
