// What the person is told: error messages (every error the server returns, in plain language
// with the protocol's words folded away as a detail), short notices, and the progress
// indicator of long operations. A lost connection is not a message: the offline banner
// (ui/offline-banner.js) says it once, for as long as it lasts.
// Conventions: messages stack in the viewport's corner and dismiss themselves after a while
// (errors later than notices); the list is an aria-live region so screen readers announce
// them. The progress indicator shows what runs and for how long; for whole-volume operations
// the server's op.progress fills the bar (fraction()) and a Cancel button sends op.cancel.

import { plainError } from "../net/plain-errors.js";

const ERROR_MS = 12000;
const NOTICE_MS = 4000;
const MAX_SHOWN = 5;
const HISTORY = 100;

export class Messages {
  constructor(doc) {
    this.list = doc.getElementById("messages");
    this.progress = doc.getElementById("progress");
    this.progressText = doc.getElementById("progress-text");
    this.progressBar = this.progress.querySelector("progress");
    this.cancelButton = doc.getElementById("progress-cancel");
    this.cancelButton.addEventListener("click", () => {
      for (const r of this.running.values()) if (r.cancel) r.cancel();
    });
    this.running = new Map(); // token -> {label, started}
    this.tick = 0;
    this.history = []; // the last HISTORY messages, {kind, text}, for the console and tests
  }

  // An Error, RpcError or ConnectionLost, in one sentence for a person; `context` names what
  // was being done when an error other than the server's answer happened.
  error(error, context = "") {
    let { text, detail } = plainError(error);
    if (error && error.name !== "RpcError" && context && context !== "protocol" && context !== "connection") text = `${context}: ${text}`;
    this.#show(text, "error", ERROR_MS, detail);
  }

  notice(text) {
    this.#show(text, "info", NOTICE_MS, "");
  }

  #show(text, kind, ms, detail) {
    this.history.push({ kind, text, detail });
    if (this.history.length > HISTORY) this.history.shift();
    const item = this.list.ownerDocument.createElement("div");
    item.className = `message ${kind}`;
    item.setAttribute("role", kind === "error" ? "alert" : "status");
    const p = item.ownerDocument.createElement("p");
    p.textContent = text;
    const body = item.ownerDocument.createElement("div");
    body.append(p);
    if (detail) {
      const more = item.ownerDocument.createElement("details");
      const summary = item.ownerDocument.createElement("summary");
      summary.textContent = "Details";
      const code = item.ownerDocument.createElement("code");
      code.textContent = detail;
      more.append(summary, code);
      body.append(more);
    }
    const close = item.ownerDocument.createElement("button");
    close.type = "button";
    close.textContent = "×";
    close.setAttribute("aria-label", "Dismiss");
    close.addEventListener("click", () => item.remove());
    item.append(body, close);
    this.list.append(item);
    while (this.list.children.length > MAX_SHOWN) this.list.firstElementChild.remove();
    setTimeout(() => item.remove(), ms);
  }

  // Shows the progress indicator while `promise` runs; resolves and rejects as it does.
  // `cancel`, when given, is what the Cancel button calls.
  async during(label, promise, cancel = null) {
    const token = {};
    this.running.set(token, { label, started: performance.now(), cancel });
    this.#updateProgress();
    try {
      return await promise;
    } finally {
      this.running.delete(token);
      this.#updateProgress();
    }
  }

  // How far the running operation is, in [0, 1] (the server's op.progress).
  fraction(f) {
    if (this.running.size) this.progressBar.value = f;
  }

  #updateProgress() {
    this.progressBar.removeAttribute("value"); // indeterminate until the server reports
    this.cancelButton.hidden = ![...this.running.values()].some((r) => r.cancel);
    if (!this.running.size) {
      this.progress.hidden = true;
      clearInterval(this.tick);
      this.tick = 0;
      return;
    }
    const render = () => {
      const [first] = this.running.values();
      const seconds = (performance.now() - first.started) / 1000;
      const more = this.running.size > 1 ? ` (+${this.running.size - 1} more)` : "";
      this.progressText.textContent = `${first.label}… ${seconds.toFixed(1)} s${more}`;
    };
    render();
    this.progress.hidden = false;
    if (!this.tick) this.tick = setInterval(render, 100);
  }
}
