// The timeline panel: the session's steps (history.list) with their authors and tools, newest
// first; hovering or focusing a step shows the volume as it was right after it (a frame the
// server renders from history, render.frame `revision`: nothing is undone), and "Fork from
// here" makes a new session starting at that step, which this page then opens.
// It owns only its DOM; the app fetches the list and the previews and does the fork
// (handlers: preview(revision) -> Promise<Blob>, fork(revision)).
// Conventions: rows are net/undo-scope.js timelineRows'; undone steps (the redo list) are shown
// struck through and cannot be forked from (PROTOCOL.md session.fork).

export class Timeline {
  constructor(doc, handlers) {
    this.doc = doc;
    this.handlers = handlers;
    this.panel = doc.getElementById("timeline-panel");
    this.list = doc.getElementById("timeline");
    this.image = doc.getElementById("timeline-preview-image");
    this.caption = doc.getElementById("timeline-preview-caption");
    this.previewUrl = null;
    this.hovered = null; // the revision whose preview is wanted now; older answers are dropped
    this.panel.addEventListener("toggle", () => this.panel.open && this.handlers.opened());
  }

  get open() {
    return this.panel.open;
  }

  // Shows the rows (oldest first as history.list gives them; listed newest first).
  show(rows, revision, readOnly) {
    const items = [];
    for (const row of [...rows].reverse()) {
      const li = this.doc.createElement("li");
      li.dataset.revision = String(row.revision);
      li.dataset.author = row.author;
      li.tabIndex = 0;
      if (row.undone) li.classList.add("undone");
      if (row.mine) li.classList.add("mine");
      const label = this.doc.createElement("span");
      label.textContent = `rev ${row.revision} · ${row.author} · ${row.tool} · ${row.time}${row.undone ? " (undone)" : ""}`;
      li.append(label);
      if (!row.undone) {
        const fork = this.doc.createElement("button");
        fork.type = "button";
        fork.className = "fork";
        fork.textContent = "Fork from here";
        fork.title = `A new session starting from revision ${row.revision}; this page opens it`;
        fork.addEventListener("click", () => this.handlers.fork(row.revision));
        li.append(fork);
      }
      li.addEventListener("mouseenter", () => this.#preview(row.revision));
      li.addEventListener("focus", () => this.#preview(row.revision));
      items.push(li);
    }
    if (!items.length) {
      const li = this.doc.createElement("li");
      li.className = "empty";
      li.textContent = "No steps yet.";
      items.push(li);
    }
    this.list.replaceChildren(...items);
    this.list.dataset.revision = String(revision);
    this.list.dataset.steps = String(rows.length);
    this.panel.dataset.readOnly = String(Boolean(readOnly));
  }

  async #preview(revision) {
    if (this.hovered === revision) return;
    this.hovered = revision;
    this.caption.textContent = `Revision ${revision}: rendering…`;
    try {
      const blob = await this.handlers.preview(revision);
      if (this.hovered !== revision) return;
      if (this.previewUrl) URL.revokeObjectURL(this.previewUrl);
      this.previewUrl = URL.createObjectURL(blob);
      this.image.src = this.previewUrl;
      this.image.hidden = false;
      this.image.dataset.revision = String(revision);
      this.caption.textContent = `The volume at revision ${revision}`;
    } catch {
      if (this.hovered === revision) this.caption.textContent = `Revision ${revision} could not be previewed.`;
      this.hovered = null;
    }
  }
}
