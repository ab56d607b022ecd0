// The frame view's supply of ray-cast frames from the server.
// Two ways, by shading (PROTOCOL.md, view.set and render.frame):
// - "lit": the session streams in `frames` mode; the server pushes a frame after every change
//   (interactive quality first, then a still one) and one at once for every view.set. Camera
//   moves send view.set, at most one in flight, at half resolution while the camera moves and
//   at full resolution once it has been still for STILL_DELAY_MS.
// - "normals", "gradient_error" and "thickness" (for inspection): the session streams `none`
//   and this asks for each frame with render.frame (PNG, exact pixels) after every camera move
//   or change of the session, one request in flight, the newest wins. "thickness" paints walls
//   thinner than THICKNESS_MIN_VU red (a typical minimum wall for printing at 1 vu = 1 mm).
// Conventions: sizes in device pixels of the canvas, capped by the server's max_frame_side;
// images decode off the main thread (createImageBitmap) and an older image that finishes
// decoding after a newer one is dropped.

import { FrameKind } from "/protocol/js/frames.js";

const STILL_DELAY_MS = 200;
export const THICKNESS_MIN_VU = 2;

export class FrameFeed {
  // onShown(): called after each frame is shown.
  constructor(session, camera, renderer, onShown = () => {}) {
    this.onShown = onShown;
    this.session = session;
    this.camera = camera;
    this.renderer = renderer;
    this.active = false;
    this.shading = "lit";
    this.received = 0; // frames shown since the page loaded
    this.last = null; // {revision, width, height, format, still} of the frame shown
    this.inFlight = false;
    this.dirty = false;
    this.movedAt = 0;
    this.stillTimer = 0;
    this.sent = null; // {key, still} of the newest request
    this.decodeSeq = 0;
    this.shownSeq = 0;
  }

  async start(shading) {
    this.active = true;
    this.shading = shading;
    this.sent = null;
    this.inFlight = false;
    if (shading !== "lit") await this.session.setView({ mode: "none" });
    this.dirty = true;
    this.renderer.requestRedraw();
  }

  async stop() {
    this.active = false;
    clearTimeout(this.stillTimer);
    this.renderer.frameImage.clear();
    await this.session.setView({ mode: "splats" });
  }

  // The camera moved: frames follow at interactive resolution, then a still one.
  cameraMoved() {
    if (!this.active) return;
    this.movedAt = performance.now();
    this.dirty = true;
    clearTimeout(this.stillTimer);
    this.stillTimer = setTimeout(() => {
      this.dirty = true;
      this.renderer.requestRedraw();
    }, STILL_DELAY_MS + 10);
  }

  // The session changed: in pull mode that needs a new frame (pushes come by themselves).
  sessionChanged() {
    if (this.active && this.shading !== "lit") {
      this.dirty = true;
      this.renderer.requestRedraw();
    }
  }

  // After a rejoin the server streams splats again: ask for the frame mode anew.
  rejoined() {
    if (this.active) this.start(this.shading).catch(() => {});
  }

  // Called once per display frame, before drawing: sends the newest request if one is due.
  tick() {
    if (!this.active || !this.session.connected || this.inFlight) return;
    const still = performance.now() - this.movedAt >= STILL_DELAY_MS;
    const size = this.#size(still);
    const camera = this.camera.toProtocol();
    const key = JSON.stringify([camera, size]);
    if (!this.dirty && this.sent && this.sent.key === key) return;
    this.dirty = false;
    this.sent = { key, still };
    this.inFlight = true;
    const done = () => {
      this.inFlight = false;
      this.renderer.requestRedraw();
    };
    if (this.shading === "lit") {
      this.session.setView({ mode: "frames", camera, width: size[0], height: size[1] }).then(done, done);
    } else {
      this.session
        .renderFrame({
          camera,
          width: size[0],
          height: size[1],
          format: "png",
          shading: this.shading,
          ...(this.shading === "thickness" ? { min_vu: THICKNESS_MIN_VU } : {}),
        })
        .then(({ result, frame }) => {
          if (frame) this.show(frame.header.kind, result.revision, frame.payload, still);
        })
        .then(done, done);
    }
  }

  // A frame from the server (pushed, or the answer to render.frame): decodes and shows it.
  async show(kind, revision, payload, still = true) {
    if (!this.active) return;
    const seq = ++this.decodeSeq;
    const type = kind === FrameKind.FramePng ? "image/png" : "image/jpeg";
    const bitmap = await createImageBitmap(new Blob([payload], { type }));
    if (seq < this.shownSeq || !this.active) return bitmap.close();
    this.shownSeq = seq;
    this.renderer.frameImage.set(bitmap, revision);
    this.last = { revision, width: bitmap.width, height: bitmap.height, format: type.slice(6), still };
    bitmap.close();
    ++this.received;
    this.renderer.requestRedraw();
    this.onShown();
  }

  #size(still) {
    const max = (this.session.info && this.session.info.limits && this.session.info.limits.max_frame_side) || 4096;
    const k = still ? 1 : 0.5;
    const w = Math.max(16, Math.round(this.renderer.width * k));
    const h = Math.max(16, Math.round(this.renderer.height * k));
    const s = Math.min(1, max / Math.max(w, h));
    return [Math.max(1, Math.floor(w * s)), Math.max(1, Math.floor(h * s))];
  }
}
