// The people list over the view: who is in the session (session.clients), each with their
// colour, name, what they do now (their brush's tool from presence, "sculpting" while a stroke
// is open, "view only" for view clients) and whether this page follows them. Clicking another
// person's name follows their camera (ui/follow.js); the note under the list says whom, and
// why following stopped.
// peopleRows() is pure (for the unit tests); PeopleList owns only its DOM and calls
// `onFollow(client)` on a click.
// Conventions: clients are session.clients' {client, read_only, name, color}; `presence` maps a
// client id to its newest presence entry (protocol/js PresenceBoard's), `tools` a client id to
// the last tool its brush showed (kept when the pointer leaves the model).

import { toolName } from "./tools.js";

// One row per client, this page's first: {client, name, color, you, readOnly, doing, active,
// followed}.
export function peopleRows(clients, self, presence, tools, leader) {
  const rows = clients.map((c) => {
    const brush = presence.get(c.client)?.brush;
    const tool = brush ? brush.tool : tools.get(c.client);
    let doing = "";
    if (c.read_only) doing = "view only";
    else if (tool) doing = toolName(tool).toLowerCase() + (brush && brush.active ? " · sculpting" : "");
    return {
      client: c.client,
      name: typeof c.name === "string" && c.name ? c.name : `#${c.client}`,
      color: typeof c.color === "string" ? c.color : "#808080",
      you: c.client === self,
      readOnly: Boolean(c.read_only),
      doing,
      active: Boolean(brush && brush.active),
      followed: c.client === leader,
    };
  });
  return rows.sort((a, b) => Number(b.you) - Number(a.you) || a.client - b.client);
}

// The note under the list: whom this page follows, or why it stopped.
export function followNote(leaderName, reason) {
  if (leaderName) return `Following ${leaderName}: your view copies theirs. Orbit or zoom to stop.`;
  if (reason === "you moved the camera") return "Stopped following: you moved the camera.";
  if (reason === "they left") return "Stopped following: they left the session.";
  return "";
}

export class PeopleList {
  constructor(doc, onFollow) {
    this.doc = doc;
    this.onFollow = onFollow;
    this.section = doc.getElementById("people");
    this.list = doc.getElementById("people-list");
    this.note = doc.getElementById("follow-note");
    this.shown = null; // the rows and note last shown, as JSON
  }

  // Rebuilds the rows only when they changed: presence arrives many times a second while others
  // move their pointers, and a list rebuilt each time detaches the Follow button under a click.
  show(rows, note) {
    const shown = JSON.stringify([rows, note]);
    if (shown === this.shown) return;
    this.shown = shown;
    const items = rows.map((row) => {
      const li = this.doc.createElement("li");
      li.dataset.client = String(row.client);
      li.dataset.name = row.name;
      li.dataset.doing = row.doing;
      li.dataset.followed = String(row.followed);
      if (row.you) li.classList.add("you");
      if (row.active) li.classList.add("active");
      const swatch = this.doc.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = row.color;
      const name = this.doc.createElement("span");
      name.className = "name";
      name.textContent = row.you ? `${row.name} (you)` : row.name;
      const doing = this.doc.createElement("span");
      doing.className = "doing";
      doing.textContent = row.doing;
      if (row.you) {
        li.append(swatch, name, doing);
      } else {
        const button = this.doc.createElement("button");
        button.type = "button";
        button.className = "follow";
        button.setAttribute("aria-pressed", String(row.followed));
        button.title = row.followed ? `Stop following ${row.name}` : `Follow ${row.name}'s camera`;
        button.append(swatch, name);
        button.addEventListener("click", () => this.onFollow(row.client));
        li.append(button, doing);
        if (row.followed) {
          const tag = this.doc.createElement("span");
          tag.className = "following";
          tag.textContent = "following";
          li.append(tag);
        }
      }
      return li;
    });
    this.list.replaceChildren(...items);
    this.section.hidden = rows.length < 2 && !note;
    this.section.dataset.count = String(rows.length);
    this.note.textContent = note;
    this.note.hidden = !note;
  }
}
