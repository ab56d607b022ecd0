// The share dialog: the edit link (token) and the view link (view_token) of this session. The
// secrets travel in the URL fragment only (net/session-link.js).

import { sessionLink } from "../net/session-link.js";

export class ShareDialog {
  constructor(doc) {
    this.doc = doc;
    this.dialog = doc.getElementById("share-dialog");
    for (const button of this.dialog.querySelectorAll("[data-copy]"))
      button.addEventListener("click", async () => {
        const input = doc.getElementById(button.dataset.copy);
        input.select();
        try {
          await navigator.clipboard.writeText(input.value);
          button.textContent = "Copied";
        } catch {
          button.textContent = "Select and copy by hand";
        }
      });
  }

  // info: the session.create / session.join result; a client that joined by link knows only
  // the token it joined with.
  open(pageUrl, info, joinToken, front = null) {
    const edit = info.token || (!info.read_only ? joinToken : "");
    const view = info.view_token || (info.read_only ? joinToken : "");
    const $ = (id) => this.doc.getElementById(id);
    $("share-edit").value = edit ? sessionLink(pageUrl, info.session, edit, front) : "(not known to this client)";
    $("share-view").value = view ? sessionLink(pageUrl, info.session, view, front) : "(not known to this client)";
    for (const button of this.dialog.querySelectorAll("[data-copy]"))
      button.textContent = button.dataset.copy === "share-edit" ? "Copy edit link" : "Copy view link";
    this.dialog.showModal();
  }
}
