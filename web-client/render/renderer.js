// The canvas: its WebGL2 context, its size in device pixels, and the one place that draws.
// Conventions: every redraw request between two display frames merges into one
// requestAnimationFrame; `onBeforeDraw` callbacks run first in that frame (pointer picking and
// stroke dabs happen there, once per frame rather than per pointer event). The drawing buffer
// has exactly the canvas's size in device pixels (CSS size x devicePixelRatio, from
// ResizeObserver's device-pixel box where the browser has it), so the picture is sharp and
// undistorted at any window size and pixel ratio. Views: "splats" draws the client's splats,
// "frames" the newest server frame; the brush cursor is drawn over either, and so are the other
// clients' brush rings and the marks of their edits (ui/presence-view.js sets `others`).
// Ownership: the renderer reads the SplatStore and the camera; it never changes them except
// for the camera's matrices (update()) and the store's GPU change log (sync).

import { Backdrop } from "./backdrop.js";
import { BrushCursor } from "./brush-cursor.js";

const GRID_COLOR = [0.95, 0.55, 0.2];
import { FrameImage } from "./frame-image.js";
import { SplatRenderer } from "./splat-renderer.js";

const FPS_WINDOW_MS = 1000;

export class Renderer {
  constructor(canvas, store, camera) {
    this.canvas = canvas;
    this.store = store;
    this.camera = camera;
    this.view = "splats";
    this.shading = "lit";
    this.cursorShape = { rings: [], segments: [], color: [1, 1, 1] }; // ui/sculpt.js sets it
    this.gridBox = []; // the grid's edges while the model nears them (app.js, math/grid-edge.js)
    // The others' rings and their edits' marks (math/presence-rings.js): {rings, marks: [{segments, color, alpha}]}.
    this.others = { rings: [], marks: [] };
    this.onBeforeDraw = [];
    this.onAfterDraw = [];
    this.width = 1;
    this.height = 1;
    this.frameCount = 0;
    this.lastDrawMs = 0;
    this.drawTimes = new Float64Array(240); // ring of recent draw timestamps, for fps
    this.drawTimesNext = 0;
    this.pending = 0;
    // Multisampling smooths the discs' edges where pixels are coarse; at a pixel ratio of 2 or
    // more the pixels are finer than it would help, and it costs fill rate.
    const antialias = (window.devicePixelRatio || 1) < 2;
    const gl = canvas.getContext("webgl2", { antialias, alpha: false, depth: true, powerPreference: "high-performance" });
    if (!gl) throw new Error("this browser has no WebGL2, which the splat view needs");
    this.gl = gl;
    this.#createResources();
    canvas.addEventListener("webglcontextlost", (e) => {
      e.preventDefault();
      this.lost = true;
    });
    canvas.addEventListener("webglcontextrestored", () => {
      this.lost = false;
      this.#createResources();
      this.splats.restore(this.store);
      this.requestRedraw();
    });
    this.devicePixelSize = null;
    const observer = new ResizeObserver((entries) => {
      const entry = entries[entries.length - 1];
      const box = entry.devicePixelContentBoxSize && entry.devicePixelContentBoxSize[0];
      this.devicePixelSize = box ? [box.inlineSize, box.blockSize] : null;
      this.requestRedraw();
    });
    try {
      observer.observe(canvas, { box: "device-pixel-content-box" });
    } catch {
      observer.observe(canvas);
    }
  }

  #createResources() {
    const gl = this.gl;
    this.backdrop = new Backdrop(gl);
    if (!this.splats) this.splats = new SplatRenderer(gl);
    this.frameImage = new FrameImage(gl);
    this.cursor = new BrushCursor(gl);
  }

  // Asks for a redraw in the next display frame; repeated calls before it merge into one.
  requestRedraw() {
    if (this.pending) return;
    this.pending = requestAnimationFrame((t) => {
      this.pending = 0;
      this.#frame(t);
    });
  }

  // Frames drawn in the last second, or 0 when drawing has been idle that long.
  get fps() {
    const now = performance.now();
    const n = this.drawTimes.length;
    let count = 0;
    let oldest = now;
    for (let i = 1; i <= n; ++i) {
      const t = this.drawTimes[(this.drawTimesNext - i + n) % n];
      if (!t || now - t > FPS_WINDOW_MS) break;
      oldest = t;
      ++count;
    }
    if (count < 2) return 0;
    return ((count - 1) * 1000) / Math.max(1, now - oldest);
  }

  #frame(time) {
    for (const f of this.onBeforeDraw) f(time);
    this.drawNow();
    for (const f of this.onAfterDraw) f(time);
  }

  // The viewport size in device pixels: the observer's exact device-pixel box when it agrees
  // with CSS size x devicePixelRatio (emulated screens in developer tools report an unscaled
  // box), else that product.
  #resize() {
    const dpr = window.devicePixelRatio || 1;
    const css = [Math.round(this.canvas.clientWidth * dpr), Math.round(this.canvas.clientHeight * dpr)];
    const box = this.devicePixelSize;
    const [w, h] = box && Math.abs(box[0] - css[0]) <= 2 && Math.abs(box[1] - css[1]) <= 2 ? box : css;
    const max = this.gl.getParameter(this.gl.MAX_VIEWPORT_DIMS);
    const width = Math.max(1, Math.min(w, max[0]));
    const height = Math.max(1, Math.min(h, max[1]));
    if (this.canvas.width !== width || this.canvas.height !== height) {
      this.canvas.width = width;
      this.canvas.height = height;
    }
    this.width = width;
    this.height = height;
  }

  // Draws at once (the frame loop, snapshots and the frame-time measurement call this).
  drawNow() {
    if (this.lost) return;
    const start = performance.now();
    const gl = this.gl;
    this.#resize();
    this.camera.update(this.width, this.height);
    this.splats.sync(this.store);
    gl.viewport(0, 0, this.width, this.height);
    gl.clearColor(0, 0, 0, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (this.view === "frames" && this.frameImage.hasImage) {
      this.frameImage.draw();
    } else {
      this.backdrop.draw();
      if (this.view === "splats") this.splats.draw(this.camera, this.shading);
    }
    if (this.gridBox.length) this.cursor.draw(this.camera, { rings: [], segments: this.gridBox, color: GRID_COLOR });
    for (const mark of this.others.marks) this.cursor.draw(this.camera, { rings: [], segments: mark.segments, color: mark.color, alpha: mark.alpha });
    this.cursor.draw(this.camera, { rings: this.others.rings, segments: [], color: [1, 1, 1] });
    this.cursor.draw(this.camera, this.cursorShape);
    this.lastDrawMs = performance.now() - start;
    ++this.frameCount;
    this.drawTimes[this.drawTimesNext] = start;
    this.drawTimesNext = (this.drawTimesNext + 1) % this.drawTimes.length;
  }

  // A PNG of the current view at the canvas's resolution.
  snapshot() {
    this.drawNow();
    return new Promise((resolve, reject) =>
      this.canvas.toBlob((blob) => (blob ? resolve(blob) : reject(new Error("the canvas gave no image"))), "image/png"),
    );
  }

  // Orbits the camera once around its target in `frames` display frames and times each frame
  // to the end of its GPU work (a 1-pixel readPixels waits for it). Resolves with
  // {frames, meanMs, medianMs, p95Ms, intervalMs (between display frames), points}.
  measure(frames = 60) {
    const camera = this.camera;
    const start = camera.state();
    const pixel = new Uint8Array(4);
    const times = [];
    let first = 0;
    let last = 0;
    return new Promise((resolve) => {
      const step = (now) => {
        if (!first) first = now;
        last = now;
        camera.yaw = start.yaw + (2 * Math.PI * times.length) / frames;
        const t0 = performance.now();
        this.drawNow();
        this.gl.readPixels(0, 0, 1, 1, this.gl.RGBA, this.gl.UNSIGNED_BYTE, pixel);
        times.push(performance.now() - t0);
        if (times.length < frames) return requestAnimationFrame(step);
        camera.setState(start);
        this.requestRedraw();
        const sorted = [...times].sort((a, b) => a - b);
        resolve({
          frames,
          meanMs: times.reduce((a, b) => a + b, 0) / frames,
          medianMs: sorted[Math.floor(frames / 2)],
          p95Ms: sorted[Math.min(frames - 1, Math.floor(frames * 0.95))],
          intervalMs: (last - first) / Math.max(1, frames - 1),
          points: this.store.pointCount,
          width: this.width,
          height: this.height,
        });
      };
      requestAnimationFrame(step);
    });
  }
}
