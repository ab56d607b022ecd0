// The web client: wires the session (net/), the picture (render/), the controls (ui/) and the
// camera (math/) together. It holds no protocol or drawing logic of its own, only what
// happens when: joining, splats arriving, views switching, buttons pressed.
// Conventions: world in vu of the session grid, y up. The page's URL fragment carries the
// session link (#session=ID&token=TOKEN) once a session is open, so reloading the page rejoins
// it. `window.marzipan` is this App, for looking at its state from the browser's console.

import { FRAME_HEADER_BYTES } from "/protocol/js/frames.js";
import { volumeFormats } from "/protocol/js/rpc.js";
import { CLAY_COLOR, decodeSplats } from "/protocol/js/splats.js";
import { gridBoxEdges, nearGridEdge } from "./math/grid-edge.js";
import { OrbitCamera } from "./math/orbit-camera.js";
import { scaleMesh } from "./math/mesh-scale.js";
import { RpcError } from "./net/rpc-error.js";
import { FrameFeed } from "./net/frame-feed.js";
import { PickSync } from "./net/pick-sync.js";
import { SessionClient } from "./net/session-client.js";
import { timelineRows } from "./net/undo-scope.js";
import { parseSessionLink, sessionLink } from "./net/session-link.js";
import { Renderer } from "./render/renderer.js";
import { SplatStore } from "./render/splat-store.js";
import { Controls } from "./ui/controls.js";
import { download, fileName, readFile, volumeFormatOf } from "./ui/files.js";
import { HelpDialog } from "./ui/help-dialog.js";
import { Messages } from "./ui/messages.js";
import { OfflineBanner } from "./ui/offline-banner.js";
import { PointerInput } from "./ui/pointer-input.js";
import { PresenceView } from "./ui/presence-view.js";
import { RecentSessions } from "./ui/recent-sessions.js";
import { Sculpt } from "./ui/sculpt.js";
import { ShareDialog } from "./ui/share-dialog.js";
import { installShortcuts } from "./ui/shortcuts.js";
import { StartScreen } from "./ui/start-screen.js";
import { StatusBar } from "./ui/status-bar.js";
import { Timeline } from "./ui/timeline.js";
import { GLOBAL_OPS, MASK_OPS } from "./ui/tools.js";

const STATUS_REFRESH_MS = 500;
const FRAME_TIME_FRAMES = 60;
const HINT_KEY = "marzipan.hint-dismissed";
const NAME_KEY = "marzipan.name"; // the display name this browser last gave (start screen)
const PREVIEW_SIZE = [192, 144]; // the timeline's preview, CSS pixels (index.html)

// Where the starting solids face (server/engine/solids.hpp): the Front view looks at that side.
const SOLID_FRONTS = Object.freeze({ pig: "+x" });

export class App {
  constructor(doc, win) {
    this.doc = doc;
    this.win = win;
    this.store = new SplatStore();
    this.camera = new OrbitCamera();
    this.canvas = doc.getElementById("view");
    this.renderer = new Renderer(this.canvas, this.store, this.camera);
    this.session = new SessionClient(win.location.href);
    this.messages = new Messages(doc);
    this.status = new StatusBar(doc);
    this.recent = new RecentSessions(localStorageOf(win));
    this.startScreen = new StartScreen(doc, this.recent, localStorageOf(win), NAME_KEY);
    this.offline = new OfflineBanner(doc);
    this.help = new HelpDialog(doc);
    this.shareDialog = new ShareDialog(doc);
    this.timeline = new Timeline(doc, {
      opened: () => this.#refreshTimeline(),
      preview: (revision) => this.#previewAt(revision),
      fork: (revision) => this.#fork(revision),
    });
    this.timelineLoading = null; // the history.list in flight; one at a time
    this.timelineStale = false; // the session changed while it was in flight
    this.frameFeed = new FrameFeed(this.session, this.camera, this.renderer, () =>
      this.status.frame(this.frameFeed.last, this.frameFeed.received),
    );
    this.renderer.onBeforeDraw.push(() => this.frameFeed.tick());
    this.pickSync = new PickSync(this.session, () => this.store.revision, (buffer) => this.#splats(buffer));
    this.controls = new Controls(doc, this.#controlHandlers());
    doc.getElementById("mesh-scale").addEventListener("input", () => this.#showMeshScale());
    doc.getElementById("orthographic").addEventListener("change", (e) => this.#setOrthographic(e.target.checked));
    this.sculpt = new Sculpt({
      session: this.session,
      store: this.store,
      camera: this.camera,
      renderer: this.renderer,
      controls: this.controls,
      messages: this.messages,
    });
    this.presence = new PresenceView({
      doc,
      session: this.session,
      camera: this.camera,
      renderer: this.renderer,
      sculpt: this.sculpt,
      applyCamera: (camera) => this.#followCamera(camera),
    });
    this.input = new PointerInput(this.canvas, this.camera, {
      hover: (x, y) => this.sculpt.hover(x, y),
      leave: () => this.sculpt.leave(),
      sculptGestureAt: (x, y) => this.sculpt.sculptGestureAt(x, y),
      strokeStart: (x, y, p, modifier) => this.sculpt.strokeStart(x, y, p, modifier),
      pickColor: (x, y) => this.sculpt.pickColor(x, y),
      strokeMove: (x, y, p) => this.sculpt.strokeMove(x, y, p),
      strokeEnd: () => this.sculpt.strokeEnd(),
      click: (x, y, modifier) => this.sculpt.click(x, y, modifier),
      brushStart: () => this.sculpt.brushStart(),
      pivotAt: (x, y) => this.sculpt.pivotAt(x, y),
      focusAt: (x, y) => this.#focusAt(x, y),
      twoFingerTap: () => this.controls.handlers.onUndo(),
      brushDrag: (dx, dy) => this.sculpt.brushDrag(dx, dy),
      cameraChanged: () => this.#cameraChanged(),
    });
    installShortcuts(doc, this.#shortcutActions());
    doc.getElementById("help").addEventListener("click", () => this.help.open());
    this.#installHint(doc, localStorageOf(win));
    this.#listen();
    this.joinToken = null; // the token this client holds (edit or view)
    this.front = null; // the model's front axis (math/orbit-camera.js FRONT_AXES), or null for +z
    this.fitOnNextFull = false;
    this.lastMeasure = null;
    win.setInterval(() => this.status.fps(this.renderer.fps, this.renderer.lastDrawMs), STATUS_REFRESH_MS);
    this.#updateAvailability();
  }

  // Joins the session of the page's link, or asks what to do.
  async start() {
    const link = parseSessionLink(this.win.location.hash);
    if (link) {
      try {
        await this.#open({ join: link });
        return;
      } catch (e) {
        this.startScreen.showError(`Could not join the session of this link: ${describe(e)}`);
      }
    }
    await this.#chooseSession(false);
  }

  async #chooseSession(closable) {
    for (;;) {
      const choice = await this.startScreen.choose({ closable });
      if (!choice) return;
      try {
        await this.#open(choice);
        this.startScreen.close();
        return;
      } catch (e) {
        this.startScreen.showError(describe(e));
      }
    }
  }

  // Leaves any open session, then creates or joins one.
  async #open(choice) {
    this.input.cancel();
    if (this.session.info) {
      this.session.leave();
      this.store.clear();
    }
    this.fitOnNextFull = true;
    const name = this.startScreen.name;
    if (choice.create) {
      const result = await this.session.create({ ...choice.create, name });
      this.joinToken = result.token;
      this.front = SOLID_FRONTS[choice.create.solid] || null;
    } else {
      await this.session.join({ ...choice.join, name });
      this.joinToken = choice.join.token;
      const known = this.recent.find(choice.join.session);
      this.front = choice.join.front || (known && known.front) || null;
    }
    this.camera.setFront(this.front);
    this.camera.setPreset("home");
    this.win.history.replaceState(null, "", sessionLink(this.win.location.href, this.session.info.session, this.joinToken, this.front));
    const info = this.session.info;
    this.recent.remember({ session: info.session, token: this.joinToken, readOnly: Boolean(info.read_only), size: info.size, front: this.front });
    if (this.controls.settings.view === "frames") await this.frameFeed.start(this.controls.settings.shading);
  }

  #listen() {
    const s = this.session;
    s.addEventListener("connection", (e) => {
      this.status.connection(e.detail);
      this.offline.show(e.detail);
      if (e.detail.state !== "connected") this.input.cancel();
      this.#updateAvailability();
    });
    s.addEventListener("joined", (e) => {
      const { info, rejoined } = e.detail;
      this.camera.setDomain(info.size);
      this.#showMeshScale();
      this.status.session(info);
      this.status.clients(s.clients, info.client);
      if (rejoined) {
        this.messages.notice(`Reconnected to the session at revision ${info.revision}.`);
        this.frameFeed.rejoined();
      } else {
        this.#fitModel();
      }
      this.#updateAvailability();
      this.renderer.requestRedraw();
      this.#refreshTimeline();
    });
    s.addEventListener("state", (e) => {
      this.status.state(e.detail);
      this.doc.title = `Marzipan · rev ${e.detail.revision}`;
      this.frameFeed.sessionChanged();
      this.pickSync.changed();
      this.#updateAvailability();
      this.#refreshTimeline();
    });
    s.addEventListener("clients", (e) => this.status.clients(e.detail.clients, s.info && s.info.client));
    s.addEventListener("progress", (e) => this.messages.fraction(e.detail.fraction));
    s.addEventListener("rtt", (e) => this.status.rtt(e.detail.method, e.detail.ms));
    s.addEventListener("splats", (e) => this.#splats(e.detail));
    s.addEventListener("frame", (e) => {
      const { kind, revision, payload } = e.detail;
      this.frameFeed.show(kind, revision, payload);
    });
    s.addEventListener("error", (e) => {
      const { error, context } = e.detail;
      // A lost connection fails every pending request at once; the connection message says it once.
      if (error.name !== "ConnectionLost" && error.name !== "ConnectionRefused") this.messages.error(error, context);
    });
    s.addEventListener("lost", (e) => {
      this.messages.error(e.detail.error, "rejoining");
      this.#chooseSession(false);
    });
  }

  #splats({ full, revision, payload }) {
    // Points of unpainted bricks take the session's base colour (session.create/join's base_color).
    const decoded = decodeSplats(payload, { baseColor: this.session.info?.base_color ?? CLAY_COLOR });
    if (!decoded.ok) {
      this.messages.error(new Error(`splat buffer refused (${decoded.code}): ${decoded.message}`));
      return;
    }
    if (full) this.store.applyFull(decoded, revision);
    else this.store.applyDelta(decoded, revision);
    if (full && this.fitOnNextFull) {
      this.fitOnNextFull = false;
      this.#fitModel();
      this.#cameraChanged();
    }
    this.status.splats(this.store.pointCount, this.store.bricks.size, this.store.revision);
    this.#showGridEdge();
    this.sculpt.refresh();
  }

  // The grid's box and a note while the model comes within GRID_NEAR_VU of a face.
  #showGridEdge() {
    const size = this.session.info && this.session.info.size;
    const near = Boolean(size) && nearGridEdge(this.store.bricks.values(), size);
    this.renderer.gridBox = near ? gridBoxEdges(size) : [];
    this.canvas.dataset.gridEdge = near ? "near" : "clear";
    document.getElementById("grid-note").hidden = !near;
  }

  // Reloads the timeline's steps while its panel is open: one history.list at a time, and one
  // more after it when the session changed meanwhile (session.changed, undo, a join).
  async #refreshTimeline() {
    if (!this.timeline.open || !this.session.connected) return;
    if (this.timelineLoading) {
      this.timelineStale = true;
      return;
    }
    this.timelineStale = false;
    this.timelineLoading = this.session.historyList();
    try {
      const { revision, steps } = await this.timelineLoading;
      const names = new Map(this.session.clients.map((c) => [c.client, c.name]));
      this.timeline.show(timelineRows(steps, this.session.info.client, undefined, names), revision, this.session.readOnly);
    } catch {
      // reported by the session's "error" event
    } finally {
      this.timelineLoading = null;
    }
    if (this.timelineStale) this.#refreshTimeline();
  }

  // The volume right after the step of `revision`, from this page's camera, as a PNG Blob.
  async #previewAt(revision) {
    const [width, height] = PREVIEW_SIZE;
    const { frame } = await this.session.renderFrame({ camera: this.camera.toProtocol(), width, height, format: "png", revision });
    return new Blob([frame.payload], { type: "image/png" });
  }

  // Forks the session at `revision` and opens the fork here: its link becomes the page's
  // address (the old session's link still opens the old session, which goes on without us).
  async #fork(revision) {
    this.input.cancel();
    const from = this.session.info.session;
    try {
      const result = await this.messages.during(`Forking at revision ${revision}`, this.session.fork(revision));
      this.joinToken = result.token;
      this.win.history.replaceState(null, "", sessionLink(this.win.location.href, result.session, this.joinToken, this.front));
      this.recent.remember({ session: result.session, token: this.joinToken, readOnly: false, size: result.size, front: this.front });
      this.messages.notice(`This page is now a new session forked from ${from} at revision ${result.forked_from.revision}; its link is in the address bar.`);
      if (this.controls.settings.view === "frames") await this.frameFeed.start(this.controls.settings.shading);
    } catch {
      // reported by the session's "error" event
    }
  }

  // Frames the model (its splats), or the whole domain when it has none.
  #fitModel() {
    const aspect = this.canvas.clientWidth / Math.max(1, this.canvas.clientHeight);
    if (this.store.pointCount) this.camera.fitPoints([...this.store.bricks.values()].map((b) => b.positions), aspect);
    else this.camera.fit(null, null, aspect);
  }

  // The person moved the camera (orbit, pan, zoom, presets, focus): following stops.
  #cameraChanged() {
    this.frameFeed.cameraMoved();
    this.sculpt.refresh();
    this.presence.cameraMoved();
  }

  // Following someone (ui/presence-view.js): their camera becomes this page's.
  #followCamera(camera) {
    this.camera.setFromProtocol(camera);
    this.doc.getElementById("orthographic").checked = this.camera.orthographic;
    this.frameFeed.cameraMoved();
    this.sculpt.refresh();
  }

  // The hint along the bottom of the view: dismissed once, gone for good in this browser (kept
  // in localStorage under HINT_KEY). Presses on its text reach the model (style.css).
  #installHint(doc, storage) {
    const hint = doc.getElementById("hint");
    try {
      hint.hidden = Boolean(storage && storage.getItem(HINT_KEY));
    } catch {
      // a storage that refuses reads leaves the hint shown
    }
    doc.getElementById("hint-close").addEventListener("click", () => {
      hint.hidden = true;
      try {
        if (storage) storage.setItem(HINT_KEY, "dismissed");
      } catch {
        // full or refused: dismissed for this page only
      }
    });
  }

  #updateAvailability() {
    const s = this.session;
    this.controls.setAvailability({ connected: s.connected, readOnly: s.readOnly, canUndo: s.canUndo, canRedo: s.canRedo,
                                    volumeFormats: volumeFormats(this.session.info && this.session.info.limits) });
    this.doc.getElementById("hint-text").textContent = s.readOnly
      ? "View only: drag to orbit · middle-drag to pan · wheel or pinch to zoom · ? for all shortcuts"
      : "Drag on the model to sculpt · Space+drag or right-drag to orbit · middle-drag to pan · wheel or pinch to zoom · ? for all shortcuts";
  }

  // Runs an edit that answers by itself through "error" events; the promise's rejection is
  // already reported, so it is swallowed here.
  #quietly(promise) {
    return promise.catch(() => undefined);
  }

  #controlHandlers() {
    return {
      onSettings: () => this.sculpt && this.sculpt.refresh(),
      onUndo: () => this.sculpt.editable && this.#quietly(this.session.undo()),
      onRedo: () => this.sculpt.editable && this.#quietly(this.session.redo()),
      onGlobal: (op, amount) => this.#global(op, amount),
      onCamera: (name) => this.#cameraPreset(name),
      onView: (view, shading) => this.#setView(view, shading),
      onExport: (format) => this.#exportMesh(format),
      onSaveVolume: (format) => this.#saveVolume(format),
      onLoadVolume: (file) => this.#loadVolume(file),
      onSnapshot: () => this.#snapshot(),
      onStats: () => this.#stats(),
      onMeasure: () => this.measureFrameTime(),
      onShare: () => this.shareDialog.open(this.win.location.href, this.session.info, this.joinToken, this.front),
      onNewSession: () => this.#chooseSession(Boolean(this.session.info)),
    };
  }

  #shortcutActions() {
    const c = () => this.controls;
    return {
      canvas: this.canvas,
      undo: () => this.controls.handlers.onUndo(),
      redo: () => this.controls.handlers.onRedo(),
      tool: (id) => c().setTool(id),
      radiusBy: (k) => c().setRadius(c().settings.radius * k),
      strengthBy: (d) => c().setStrength(c().secondValue + d),
      toggleView: () => c().setView(c().settings.view === "splats" ? "frames" : "splats"),
      toggleGradientError: () => c().setShading(c().settings.shading === "gradient_error" ? "lit" : "gradient_error"),
      camera: (name) => this.#cameraPreset(name),
      toggleOrthographic: () => this.#setOrthographic(!this.camera.orthographic),
      zoom: (k) => {
        this.camera.zoom(k);
        this.#cameraChanged();
      },
      orbit: (dx, dy) => {
        this.camera.orbit(dx, dy, this.canvas.clientHeight);
        this.#cameraChanged();
      },
      cancel: () => this.input.cancel(),
      help: () => this.help.open(),
    };
  }

  // Presets look along their axis at the model itself, framed as a whole.
  #cameraPreset(name) {
    this.camera.setPreset(name);
    this.#fitModel();
    this.#cameraChanged();
  }

  #setOrthographic(on) {
    this.camera.setOrthographic(on);
    this.doc.getElementById("orthographic").checked = on;
    this.#cameraChanged();
  }

  #focusAt(x, y) {
    const hit = this.sculpt.pick(x, y);
    if (!hit) return;
    this.camera.focus(hit.point);
    this.#cameraChanged();
  }

  async #setView(view, shading) {
    this.renderer.view = view;
    this.renderer.shading = shading === "normals" ? "normals" : "lit";
    this.pickSync.setActive(view === "frames");
    try {
      if (view === "frames") await this.frameFeed.start(shading);
      else if (this.frameFeed.active) await this.frameFeed.stop();
    } catch {
      // reported by the session's "error" event
    }
    this.renderer.requestRedraw();
  }

  async #global(op, amount) {
    if (MASK_OPS[op]) {
      await this.#quietly(this.messages.during(`${MASK_OPS[op].label} the whole volume`, this.session.request(op, {})));
      return;
    }
    const spec = GLOBAL_OPS[op];
    if (!(amount >= spec.min && amount <= spec.max)) {
      this.messages.error(new Error(`${spec.amount} must be between ${spec.min} and ${spec.max}`));
      return;
    }
    const work =
      op === "smooth"
        ? this.session.applyTool({ tool: "smooth", global: true, iterations: Math.round(amount), strength: this.controls.settings.strength })
        : this.session.morph(op, amount);
    const cancel = () => this.session.cancel().catch(() => {});
    await this.#quietly(this.messages.during(`${spec.label} the whole volume`, work, cancel));
  }

  async #exportMesh(format) {
    try {
      const mmPerVu = this.#meshScale();
      if (mmPerVu === null) return;
      const { result, frame } = await this.messages.during(`Exporting ${format.toUpperCase()}`, this.session.exportMesh(format));
      const bytes = scaleMesh(format, frame.payload, mmPerVu);
      download(bytes, fileName(this.session.info.session, result.revision, format));
      const box = this.store.pointBounds();
      const size = box ? ` The model measures ${box.hi.map((h, k) => formatMm((h - box.lo[k]) * mmPerVu)).join(" × ")} mm.` : "";
      this.messages.notice(`${format.toUpperCase()} at ${formatMm(mmPerVu)} mm per vu: ${result.triangles.toLocaleString("en")} triangles, ${formatBytes(bytes.byteLength)}.${size}`);
    } catch {
      // reported by the session's "error" event
    }
  }

  // The "Mesh scale" field in mm per vu, or null (and a message) when it is not a usable number.
  #meshScale() {
    const field = document.getElementById("mesh-scale");
    const v = Number(field.value);
    if (v > 0 && Number.isFinite(v)) return v;
    this.messages.error(new Error(`The mesh scale must be a positive number of millimetres per vu, not "${field.value}".`));
    return null;
  }

  // The grid's side in mm at the chosen scale, beside the field.
  #showMeshScale() {
    const size = this.session.info && this.session.info.size;
    const v = Number(document.getElementById("mesh-scale").value);
    document.getElementById("mesh-scale-grid").textContent = size && v > 0 ? `The grid is ${size.map((n) => formatMm(n * v)).join(" × ")} mm.` : "";
  }

  async #saveVolume(format) {
    try {
      const { result, frame } = await this.messages.during("Saving the volume", this.session.saveVolume(format));
      download(frame.payload, fileName(this.session.info.session, result.revision, format));
    } catch {
      // reported by the session's "error" event
    }
  }

  async #loadVolume(file) {
    const bytes = await readFile(file);
    const limit = this.session.info.limits && this.session.info.limits.max_binary_bytes;
    if (limit && bytes.byteLength + FRAME_HEADER_BYTES > limit) {
      this.messages.error(new Error(`${file.name} is ${formatBytes(bytes.byteLength)}, over the server's upload limit of ${formatBytes(limit - FRAME_HEADER_BYTES)}`));
      return;
    }
    const format = volumeFormatOf(file.name);
    if (!volumeFormats(this.session.info.limits).includes(format)) {
      this.messages.error(new Error(`${file.name} is an OpenVDB file; this server was built without OpenVDB and loads .mzv files only`));
      return;
    }
    await this.#quietly(this.messages.during(`Loading ${file.name}`, this.session.loadVolume(bytes, format)));
  }

  async #snapshot() {
    const blob = await this.renderer.snapshot();
    const info = this.session.info;
    download(blob, fileName(info ? info.session : "nosession", this.session.revision, "png"));
  }

  async #stats() {
    try {
      this.status.stats(await this.messages.during("Measuring the volume", this.session.stats()));
    } catch {
      // reported by the session's "error" event
    }
  }

  // Orbits once and times every frame (render/renderer.js, measure()); the result shows in the
  // session details.
  async measureFrameTime(frames = FRAME_TIME_FRAMES) {
    const m = await this.messages.during("Measuring the frame time", this.renderer.measure(frames));
    this.lastMeasure = m;
    this.status.frameTime(m);
    this.messages.notice(`Frame time ${m.meanMs.toFixed(1)} ms (p95 ${m.p95Ms.toFixed(1)} ms) for ${m.points.toLocaleString("en")} points.`);
    return m;
  }
}

// The browser's localStorage, or null where it is refused (private modes, sandboxed frames).
function localStorageOf(win) {
  try {
    return win.localStorage;
  } catch {
    return null;
  }
}

function describe(e) {
  if (e instanceof RpcError) return `${e.message} [${e.code} ${e.codeName}]`;
  if (e && e.name === "ConnectionLost") return "the connection closed before the server answered";
  return e && e.message ? e.message : String(e);
}

// Millimetres with up to three decimals, no trailing zeros.
function formatMm(v) {
  return String(Number(v.toFixed(3)));
}

function formatBytes(n) {
  if (n < 1024) return `${n} B`;
  if (n < 1048576) return `${(n / 1024).toFixed(1)} KiB`;
  return `${(n / 1048576).toFixed(1)} MiB`;
}
