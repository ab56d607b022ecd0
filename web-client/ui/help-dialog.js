// The shortcuts overlay (the ? key or button): every gesture and key, built from the same
// tables the input code uses (ui/gesture-map.js, ui/shortcuts.js), so it cannot drift from them.

import { GESTURE_HELP } from "./gesture-map.js";
import { KEY_HELP } from "./shortcuts.js";

export class HelpDialog {
  constructor(doc) {
    this.dialog = doc.getElementById("help-dialog");
    fill(doc, this.dialog.querySelector("#help-gestures tbody"), GESTURE_HELP);
    fill(doc, this.dialog.querySelector("#help-keys tbody"), KEY_HELP);
  }

  open() {
    if (!this.dialog.open) this.dialog.showModal();
  }
}

function fill(doc, body, rows) {
  for (const row of rows) {
    const tr = doc.createElement("tr");
    for (const cell of row) {
      const td = doc.createElement("td");
      td.textContent = cell || "—";
      tr.append(td);
    }
    body.append(tr);
  }
}
