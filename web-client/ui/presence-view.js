// Sculpting together, as this page shows and tells it (PROTOCOL.md "Presence"): it sends this
// page's brush and camera (net/presence-sender.js), keeps the others' newest presence
// (protocol/js PresenceBoard), draws their brush rings with name labels over the model and a
// brief mark of the region each other client's edit changed (math/presence-rings.js, drawn by
// render/renderer.js), lists the session's people (ui/people.js) and follows a person's camera
// (ui/follow.js).
// Conventions: times from performance.now(); a presence's `seenAt` is when it arrived. An
// edit's author and region come with its session.changed (`by`, `roi`); this page's own edits
// are not marked. Handlers: applyCamera(camera) puts a followed camera into the page's view.

import { PRESENCE_INTERVAL_MS, PresenceBoard, presenceParams } from "/protocol/js/presence.js";
import { EditMarks, presenceRings } from "../math/presence-rings.js";
import { PresenceSender, STALE_MS, composePresence } from "../net/presence-sender.js";
import { Follow } from "./follow.js";
import { PeopleList, followNote, peopleRows } from "./people.js";
import { TOOLS, toolName } from "./tools.js";

const STALE_CHECK_MS = 1000;
const STOPPED_NOTE_MS = 6000; // how long the note says why following stopped
const MARK_LOG = 16;

export class PresenceView {
  constructor({ doc, session, camera, renderer, sculpt, applyCamera }) {
    Object.assign(this, { doc, session, camera, renderer, sculpt, applyCamera });
    this.board = new PresenceBoard();
    this.seenAt = new Map(); // client -> when its newest presence arrived
    this.tools = new Map(); // client -> the last tool its brush showed
    this.marks = new EditMarks();
    this.shown = []; // the rings drawn last: [{client, center, radius, active}]
    this.marked = []; // the newest MARK_LOG edits marked: [{client, color, roi}] (for a look from the console)
    this.follow = new Follow((state) => this.#followChanged(state));
    this.noteTimer = 0;
    this.people = new PeopleList(doc, (client) => this.#toggleFollow(client));
    this.labels = doc.getElementById("presence-labels");
    this.sender = new PresenceSender({
      compose: () => this.#compose(),
      send: (params) => session.sendPresence(params),
      intervalMs: PRESENCE_INTERVAL_MS,
    });
    sculpt.onCursor = () => this.sender.poke();
    renderer.onBeforeDraw.push(() => this.#beforeDraw());
    renderer.onAfterDraw.push(() => this.marks.size && this.renderer.requestRedraw());
    this.#listen();
    setInterval(() => this.#checkStale(), STALE_CHECK_MS);
  }

  // This page's person moved the camera: following stops, and the others hear of the camera.
  cameraMoved() {
    this.follow.userMoved();
    this.sender.poke();
  }

  // The camera changed by following: the others hear of it (following goes on).
  cameraFollowed() {
    this.sender.poke();
  }

  #listen() {
    const s = this.session;
    s.addEventListener("presence", (e) => this.board.handle({ method: "presence", params: e.detail }));
    this.board.addEventListener("presence", (e) => this.#presence(e.presence));
    this.board.addEventListener("gone", (e) => {
      this.seenAt.delete(e.client);
      this.tools.delete(e.client);
      this.follow.gone(e.client);
      this.#changed();
    });
    s.addEventListener("joined", (e) => {
      // Ids and presence of a session left behind (or of before a drop) mean nothing now: the
      // others' refreshes bring theirs back within PRESENCE_REFRESH_MS.
      this.board.clear();
      this.seenAt.clear();
      this.tools.clear();
      this.marks.clear();
      if (!e.detail.rejoined) this.follow.reset();
      this.sender.resend();
      this.#changed();
    });
    let known = new Set();
    s.addEventListener("clients", (e) => {
      const ids = new Set(e.detail.clients.map((c) => c.client));
      // Someone new knows nothing of this page yet: tell them now rather than at the next move.
      if ([...ids].some((id) => !known.has(id))) this.sender.resend();
      for (const id of known) if (!ids.has(id)) this.follow.gone(id);
      known = ids;
      this.#changed();
    });
    s.addEventListener("state", (e) => {
      const { by, roi } = e.detail;
      if (typeof by !== "number" || !roi || !s.info || by === s.info.client) return;
      const author = s.clients.find((c) => c.client === by);
      if (!author || !this.marks.add(by, roi, author.color, performance.now())) return;
      this.marked = [...this.marked.slice(1 - MARK_LOG), { client: by, color: author.color, roi }];
      this.renderer.requestRedraw();
    });
  }

  #presence(entry) {
    this.seenAt.set(entry.client, performance.now());
    if (entry.brush) this.tools.set(entry.client, entry.brush.tool);
    const camera = this.follow.cameraFrom(entry);
    if (camera) {
      this.applyCamera(camera);
      this.cameraFollowed();
    }
    this.#changed();
  }

  #toggleFollow(client) {
    const camera = this.follow.toggle(client, (id) => this.board.others.get(id)?.camera);
    if (camera) {
      this.applyCamera(camera);
      this.cameraFollowed();
    }
  }

  #followChanged({ following, reason }) {
    clearTimeout(this.noteTimer);
    if (!following && reason)
      this.noteTimer = setTimeout(() => {
        this.follow.forgetReason();
        this.#showPeople();
      }, STOPPED_NOTE_MS);
    this.#showPeople();
  }

  #changed() {
    this.#showPeople();
    this.renderer.requestRedraw();
  }

  #showPeople() {
    const s = this.session;
    const self = s.info ? s.info.client : null;
    const rows = peopleRows(s.info ? s.clients : [], self, this.board.others, this.tools, this.follow.leader);
    const leader = rows.find((r) => r.followed);
    this.people.show(rows, followNote(leader ? leader.name : null, this.follow.reason));
  }

  #compose() {
    const s = this.session;
    if (!s.connected || !s.info) return null;
    return composePresence({ brush: this.sculpt.presenceBrush, camera: this.camera.toProtocol(), readOnly: s.readOnly }, presenceParams);
  }

  // The others in the session now, with when each was last heard of.
  #others() {
    const present = new Set(this.session.clients.map((c) => c.client));
    return [...this.board.others.values()].filter((o) => present.has(o.client)).map((o) => ({ ...o, seenAt: this.seenAt.get(o.client) ?? -Infinity }));
  }

  #beforeDraw() {
    const canvas = this.renderer.canvas;
    const [width, height] = [canvas.clientWidth, canvas.clientHeight];
    this.camera.update(width, height);
    const now = performance.now();
    const { rings, labels } = presenceRings(this.#others(), this.camera, width, height, now, STALE_MS);
    this.renderer.others = { rings, marks: this.marks.marks(now) };
    this.shown = rings.map((r) => ({ client: r.client, center: r.center, radius: r.radius, active: r.primary }));
    canvas.dataset.rings = String(rings.length);
    canvas.dataset.marks = String(this.renderer.others.marks.length);
    this.#placeLabels(labels);
  }

  #placeLabels(labels) {
    const doc = this.doc;
    const items = labels.map((l) => {
      const el = doc.createElement("span");
      el.className = "presence-label";
      el.dataset.client = String(l.client);
      el.dataset.active = String(l.active);
      el.textContent = l.name;
      // the tool's icon follows the name (style.css, generated content: the text stays the name)
      const tool = TOOLS.find((t) => t.id === l.tool);
      el.dataset.tool = l.tool;
      el.dataset.icon = tool ? tool.icon : "";
      el.title = `${l.name}: ${toolName(l.tool)}`;
      el.style.left = `${l.x}px`;
      el.style.top = `${l.y}px`;
      el.style.borderColor = l.color;
      el.style.setProperty("--person", l.color);
      el.hidden = !l.visible;
      return el;
    });
    this.labels.replaceChildren(...items);
  }

  // A ring drawn but no longer confirmed goes at the next draw.
  #checkStale() {
    const now = performance.now();
    if (this.shown.some((r) => now - (this.seenAt.get(r.client) ?? -Infinity) > STALE_MS)) this.renderer.requestRedraw();
  }
}
