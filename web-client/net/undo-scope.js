// Which undo a person means (PROTOCOL.md, history.undo `scope`), and what the timeline shows of
// each step of history.list. Pure functions, no DOM, for the unit tests; tools are named as the
// palette names them (ui/tools.js, from the tool registry).
// Conventions: clients are the session's {client, read_only} list (session.clients); `self` is
// this page's client id; steps are history.list's step objects.

import { toolName } from "../ui/tools.js";

// "mine" while another client who can edit is in the session, so that Ctrl+Z never takes back a
// collaborator's stroke; "session" when this page is the only editor (viewers make no steps):
// then the session's newest step is this page's or that of someone who left, and undoing it
// is what a person alone expects.
export function undoScope(clients, self) {
  return clients.some((c) => c.client !== self && !c.read_only) ? "mine" : "session";
}

// The name of a step's author: "you", their display name (history.list's `name`, since 1.2),
// "#5" when the step has none, or "someone" when the server did not record the author.
export function authorName(client, self, name) {
  if (client === null || client === undefined) return "someone";
  if (client === self) return "you";
  return typeof name === "string" && name ? name : `#${client}`;
}

// What the person reads when an undo (or redo) of their own step is refused because a later
// step changed the same bricks: who, at which revision, and what to do instead. `conflict` is
// protocol/js undoConflictOf's {client, revision, step}; `redo` says which request it was;
// `names` maps client ids to display names (session.clients), for naming the other person.
export function undoConflictText(conflict, redo, self = null, names = new Map()) {
  const name = names.get(conflict.client);
  const other = name ? `${name} (client #${conflict.client})` : `client #${conflict.client}`;
  const who = conflict.client === null ? "a later step" : conflict.client === self ? "your own later step" : other;
  const verb = redo ? "redo" : "undo";
  return (
    `Cannot ${verb} your step at revision ${conflict.step}: ${who} changed the same place at revision ${conflict.revision}. ` +
    `Nothing changed; ${conflict.client === self ? "undo that step first" : "ask them to undo theirs first"}, or fork from the timeline.`
  );
}

// The steps that are no tool (history.list `tool`), as a person reads them.
const OTHER_STEPS = {
  morph: "whole volume",
  "volume.load": "load .mzv",
};

// One timeline row per step: {revision, author, tool, time ("HH:MM:SS" local), undone, mine}.
// `names` maps client ids to the display names of the clients in the session now
// (session.clients): a step without a `name` of its own is named after its author while they
// are there (the server records names on steps only from 1.2 on, and may leave them out).
export function timelineRows(steps, self, timeOf = localTime, names = new Map()) {
  return steps.map((s) => ({
    revision: s.revision,
    author: authorName(s.client, self, s.name || names.get(s.client)),
    tool: Object.hasOwn(OTHER_STEPS, s.tool) ? OTHER_STEPS[s.tool] : toolName(s.tool),
    time: timeOf(s.time_ms),
    undone: Boolean(s.undone),
    mine: s.client === self,
  }));
}

function localTime(ms) {
  const d = new Date(ms);
  return [d.getHours(), d.getMinutes(), d.getSeconds()].map((v) => String(v).padStart(2, "0")).join(":");
}
