// The start screen: create a session (grid size, starting solid), join one by its link, or
// reopen one of the recent sessions this browser keeps (ui/recent-sessions.js). It resolves
// with what the person chose; the app does the connecting and reports failures back with
// showError(), leaving the screen open for another try. Opened while a session is open, it
// says that choosing leaves that session. It also asks for the person's display name (shown to
// the others in the session, PROTOCOL.md "Presence"), remembered in localStorage under
// `nameKey` and used for links opened without this screen too.

import { parseSessionLink } from "../net/session-link.js";

export class StartScreen {
  // recent: a RecentSessions; storage: localStorage or null.
  constructor(doc, recent, storage = null, nameKey = "marzipan.name") {
    this.doc = doc;
    this.recent = recent;
    this.storage = storage;
    this.nameKey = nameKey;
    this.nameField = doc.getElementById("your-name");
    this.nameField.value = this.#storedName();
    this.nameField.addEventListener("change", () => this.#storeName(this.nameField.value.trim()));
    this.dialog = doc.getElementById("start");
    this.error = doc.getElementById("start-error");
    this.dialog.addEventListener("cancel", (e) => {
      if (!this.closable) e.preventDefault();
    });
    this.closable = false;
  }

  // Opens the screen; resolves with {create: {size, solid}} or {join: {session, token}}.
  // `closable`: the Escape key may close it (when a session is already open); then it resolves
  // with null.
  choose({ closable = false } = {}) {
    const $ = (id) => this.doc.getElementById(id);
    this.closable = closable;
    this.error.textContent = "";
    this.#setBusy(false);
    $("start-leaving").hidden = !closable;
    if (!this.dialog.open) this.dialog.showModal();
    return new Promise((resolve) => {
      this.#listRecent((link) => finish({ join: link }));
      const create = (e) => {
        e.preventDefault();
        finish({ create: { size: Number($("create-size").value), solid: $("create-solid").value } });
      };
      const join = (e) => {
        e.preventDefault();
        const link = parseSessionLink($("join-link").value.trim());
        if (!link) {
          this.error.textContent = "That is not a session link: it must end in #session=…&token=….";
          return;
        }
        finish({ join: link });
      };
      const cancel = () => finish(null);
      const finish = (choice) => {
        $("create-form").removeEventListener("submit", create);
        $("join-form").removeEventListener("submit", join);
        this.dialog.removeEventListener("close", cancel);
        if (choice) this.#setBusy(true);
        resolve(choice);
      };
      $("create-form").addEventListener("submit", create);
      $("join-form").addEventListener("submit", join);
      this.dialog.addEventListener("close", cancel);
    });
  }

  // The recent sessions as buttons that reopen them (and forget them).
  #listRecent(open) {
    const doc = this.doc;
    const entries = this.recent.list();
    const list = doc.getElementById("recent-list");
    list.replaceChildren();
    doc.getElementById("recent").hidden = entries.length === 0;
    for (const e of entries) {
      const li = doc.createElement("li");
      const button = doc.createElement("button");
      button.type = "button";
      button.className = "recent-open";
      button.dataset.session = e.session;
      const when = new Date(e.openedAt).toLocaleString();
      button.textContent = `${e.size.join("×")} · ${e.readOnly ? "view only" : "edit"} · ${when}`;
      button.title = `Session ${e.session}`;
      button.addEventListener("click", () => open({ session: e.session, token: e.token, front: e.front || null }));
      const forget = doc.createElement("button");
      forget.type = "button";
      forget.textContent = "×";
      forget.setAttribute("aria-label", "Forget this session in this browser");
      forget.addEventListener("click", () => {
        this.recent.forget(e.session);
        li.remove();
        doc.getElementById("recent").hidden = this.recent.list().length === 0;
      });
      li.append(button, forget);
      list.append(li);
    }
  }

  // The display name to give the server: the field's (as stored when it last changed), "" for
  // none (the server then says "Sculptor N").
  get name() {
    const typed = this.nameField.value.trim();
    if (typed) this.#storeName(typed);
    return typed || this.#storedName();
  }

  #storedName() {
    try {
      return (this.storage && this.storage.getItem(this.nameKey)) || "";
    } catch {
      return "";
    }
  }

  #storeName(name) {
    try {
      if (this.storage) name ? this.storage.setItem(this.nameKey, name) : this.storage.removeItem(this.nameKey);
    } catch {
      // refused or full: the name holds for this page only
    }
  }

  showError(text) {
    this.error.textContent = text;
  }

  close() {
    if (this.dialog.open) this.dialog.close();
  }

  #setBusy(busy) {
    for (const id of ["create-button", "join-button"]) this.doc.getElementById(id).disabled = busy;
  }
}
