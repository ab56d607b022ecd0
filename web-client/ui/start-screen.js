// The start screen: create a session (grid size, starting solid) or join one by its link.
// It resolves with what the person chose; the app does the connecting and reports failures
// back with showError(), leaving the screen open for another try.

import { parseSessionLink } from "../net/session-link.js";

export class StartScreen {
  constructor(doc) {
    this.doc = doc;
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
    if (!this.dialog.open) this.dialog.showModal();
    return new Promise((resolve) => {
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
