// The side panel: the tool palette, brush settings, whole-volume operations, history, view,
// files and session details. It owns `settings`, which the sculpting code reads, and calls the
// app's handlers for actions; it never talks to the server itself. The palette and the
// whole-volume menu are built from the tool registry (ui/tools.js), and the brush controls a
// tool shows follow the parameters it takes.
// Conventions: radius in vu (0.5 to 1024, the server's range; the slider covers 1 to 64 and
// the keys go beyond); strength in (0, 1] for tools that take it; for the others (CSG) the same
// slider sets the blend, a fraction of the radius in [0, 1]; a warp's strength is its own
// (warpStrength, 1 to begin with: a grab then puts the anchor where the pointer points, the
// server moving it by strength times the drag), so that the brushes' gentler strength does not
// carry over; the radius stays within the selected tool's range (the registry's: warps 1 to
// 64 vu, elastic grab to 21.3); symmetry as a list of axes ("x", "y", "z"); lazy: the stroke stabiliser's slack in CSS pixels (0 = off); buildUp: strokes of
// tools that take a height add with every message instead of standing at a height
// (net/stroke-sender.js).

import { GLOBAL_OPS, GROUPS, MASK_OPS, TOOLS, toolById } from "./tools.js";

// Shadings only the server's ray caster draws: choosing one switches to the frame view.
const FRAMES_ONLY = new Set(["gradient_error", "thickness"]);

export const RADIUS_MIN = 0.5;
export const RADIUS_MAX = 1024;

export class Controls {
  constructor(doc, handlers) {
    this.doc = doc;
    this.handlers = handlers;
    this.settings = {
      tool: "add_blob",
      radius: 8,
      strength: 0.5,
      warpStrength: 1,
      blend: 0.2,
      shape: "sphere",
      symmetry: [],
      view: "splats",
      shading: "lit",
      lazy: 0,
      buildUp: false,
      paintColor: [200, 40, 30], // the paint tool's colour, sRGB bytes
    };
    const $ = (id) => doc.getElementById(id);
    this.$ = $;
    this.#buildPalette();
    this.#buildQuickbar();

    this.radius = $("radius");
    this.strength = $("strength");
    this.radius.addEventListener("input", () => this.setRadius(Number(this.radius.value)));
    this.strength.addEventListener("input", () => this.setStrength(Number(this.strength.value)));
    $("shape").addEventListener("change", (e) => (this.settings.shape = e.target.value));
    $("build-up").addEventListener("change", (e) => (this.settings.buildUp = e.target.checked));
    $("paint-color").value = hexOf(this.settings.paintColor);
    $("paint-color").addEventListener("input", (e) => this.setPaintColor(rgbOf(e.target.value)));
    $("lazy").addEventListener("input", (e) => {
      this.settings.lazy = Number(e.target.value);
      this.#syncBrush();
    });
    for (const axis of ["x", "y", "z"])
      $(`mirror-${axis}`).addEventListener("change", () => {
        this.settings.symmetry = ["x", "y", "z"].filter((a) => $(`mirror-${a}`).checked);
        handlers.onSettings();
      });

    const op = $("global-op");
    for (const [name, spec] of Object.entries(GLOBAL_OPS)) op.append(new Option(spec.menu, name));
    for (const [name, spec] of Object.entries(MASK_OPS)) op.append(new Option(spec.menu, name));
    op.addEventListener("change", () => this.#globalOpChanged());
    $("global-apply").addEventListener("click", () => {
      const amount = Number($("global-amount").value);
      handlers.onGlobal(op.value, amount);
    });
    this.#globalOpChanged();

    $("undo").addEventListener("click", () => handlers.onUndo());
    $("redo").addEventListener("click", () => handlers.onRedo());
    for (const input of doc.querySelectorAll('input[name="view"]'))
      input.addEventListener("change", () => input.checked && this.setView(input.value));
    $("shading").addEventListener("change", (e) => this.setShading(e.target.value));
    for (const b of doc.querySelectorAll("[data-camera]")) b.addEventListener("click", () => handlers.onCamera(b.dataset.camera));
    for (const b of doc.querySelectorAll("[data-export]")) b.addEventListener("click", () => handlers.onExport(b.dataset.export));
    $("save-volume").addEventListener("click", () => handlers.onSaveVolume("mzv"));
    $("save-vdb").addEventListener("click", () => handlers.onSaveVolume("vdb"));
    $("load-volume").addEventListener("change", (e) => {
      const file = e.target.files[0];
      e.target.value = "";
      if (file) handlers.onLoadVolume(file);
    });
    $("snapshot").addEventListener("click", () => handlers.onSnapshot());
    $("stats-refresh").addEventListener("click", () => handlers.onStats());
    $("measure-fps").addEventListener("click", () => handlers.onMeasure());
    $("share").addEventListener("click", () => handlers.onShare());
    $("new-session").addEventListener("click", () => handlers.onNewSession());
    this.#syncBrush();
  }

  get tool() {
    return toolById(this.settings.tool);
  }

  // One row of the grid per group: its name, then its tools, each an icon, a label and its key.
  #buildPalette() {
    const list = this.$("tool-list");
    for (const group of GROUPS) {
      const name = this.doc.createElement("span");
      name.className = "tool-group";
      name.textContent = group.name;
      name.title = group.description;
      list.append(name);
      for (const tool of group.tools) {
        const label = this.doc.createElement("label");
        label.title = `${tool.label} (key ${tool.key.toUpperCase()})`;
        const input = this.doc.createElement("input");
        input.type = "radio";
        input.name = "tool";
        input.value = tool.id;
        input.checked = tool.id === this.settings.tool;
        input.setAttribute("aria-keyshortcuts", tool.key.toUpperCase());
        input.addEventListener("change", () => input.checked && this.setTool(tool.id));
        const icon = this.doc.createElement("span");
        icon.className = "tool-icon";
        icon.setAttribute("aria-hidden", "true");
        icon.textContent = tool.icon;
        const kbd = this.doc.createElement("kbd");
        kbd.textContent = tool.key.toUpperCase();
        label.append(input, icon, tool.label, kbd);
        list.append(label);
      }
    }
  }

  // Small screens (style.css) show a compact toolbar over the view instead of scrolling to the
  // panel: the tools and undo/redo, the same actions as the panel's.
  #buildQuickbar() {
    const bar = this.$("quickbar");
    for (const tool of TOOLS) {
      const b = this.doc.createElement("button");
      b.type = "button";
      b.dataset.tool = tool.id;
      b.textContent = tool.short;
      b.title = tool.label;
      b.setAttribute("aria-pressed", String(tool.id === this.settings.tool));
      b.addEventListener("click", () => this.setTool(tool.id));
      bar.append(b);
    }
    for (const [id, label, action] of [["quick-undo", "Undo", () => this.handlers.onUndo()], ["quick-redo", "Redo", () => this.handlers.onRedo()]]) {
      const b = this.doc.createElement("button");
      b.type = "button";
      b.id = id;
      b.textContent = label;
      b.disabled = true;
      b.addEventListener("click", action);
      bar.append(b);
    }
  }

  setTool(id) {
    this.settings.tool = toolById(id).id;
    this.settings.radius = this.#clampRadius(this.settings.radius);
    for (const input of this.doc.querySelectorAll('input[name="tool"]')) input.checked = input.value === this.settings.tool;
    for (const b of this.doc.querySelectorAll("#quickbar [data-tool]")) b.setAttribute("aria-pressed", String(b.dataset.tool === this.settings.tool));
    this.#syncBrush();
    this.handlers.onSettings();
  }

  // The paint colour, [r, g, b] in 0..255 (the colour input, or Alt+click's pick).
  setPaintColor(rgb) {
    this.settings.paintColor = rgb.map((c) => Math.max(0, Math.min(255, Math.round(c))));
    this.$("paint-color").value = hexOf(this.settings.paintColor);
    this.handlers.onSettings();
  }

  setRadius(r) {
    this.settings.radius = this.#clampRadius(Math.round(r * 2) / 2);
    this.#syncBrush();
    this.handlers.onSettings();
  }

  #clampRadius(r) {
    const [lo, hi] = this.tool.radiusRange || [RADIUS_MIN, RADIUS_MAX];
    return Math.min(hi, RADIUS_MAX, Math.max(lo, RADIUS_MIN, r));
  }

  // The strength the selected tool strokes with: a warp's own, else the brushes'.
  get toolStrength() {
    return this.tool.warp ? this.settings.warpStrength : this.settings.strength;
  }

  // The second slider: strength for the tools that take it, else the blend (CSG tools).
  setStrength(s) {
    const strength = Math.min(1, Math.max(0.05, Math.round(s * 20) / 20));
    if (this.#sliderIsBlend) this.settings.blend = Math.min(1, Math.max(0, s));
    else if (this.tool.warp) this.settings.warpStrength = strength;
    else this.settings.strength = strength;
    this.#syncBrush();
    this.handlers.onSettings();
  }

  get secondValue() {
    return this.#sliderIsBlend ? this.settings.blend : this.toolStrength;
  }

  get #sliderIsBlend() {
    return !this.tool.takes.has("strength") && this.tool.takes.has("blend");
  }

  setView(view) {
    this.settings.view = view;
    for (const input of this.doc.querySelectorAll('input[name="view"]')) input.checked = input.value === view;
    if (view === "splats" && FRAMES_ONLY.has(this.settings.shading)) this.#setShadingControl("lit");
    this.handlers.onView(view, this.settings.shading);
  }

  setShading(shading) {
    this.#setShadingControl(shading);
    // Gradient error exists only in the server's frames.
    if (FRAMES_ONLY.has(shading) && this.settings.view !== "frames") return this.setView("frames");
    this.handlers.onView(this.settings.view, shading);
  }

  #setShadingControl(shading) {
    this.settings.shading = shading;
    this.$("shading").value = shading;
  }

  #syncBrush() {
    const s = this.settings;
    const blend = this.#sliderIsBlend;
    this.radius.value = String(Math.min(64, s.radius));
    this.$("radius-value").textContent = `${s.radius} vu`;
    this.$("strength-name").textContent = blend ? "Blend" : "Strength";
    this.strength.min = blend ? "0" : "0.05";
    this.strength.value = String(this.secondValue);
    this.$("strength-value").textContent = blend ? `${Math.round(s.blend * 100)}% of radius` : this.toolStrength.toFixed(2);
    this.$("shape-row").hidden = !this.tool.takes.has("shape");
    this.$("lazy-value").textContent = s.lazy ? `${s.lazy} px` : "off";
    // warps take no symmetry (the server refuses it); a tool without strength or blend no slider
    this.doc.querySelector(".symmetry").hidden = this.tool.kind !== "stroke" || Boolean(this.tool.warp);
    this.$("strength-label").hidden = this.$("strength-help").hidden = !this.tool.takes.has("strength") && !blend;
    this.$("build-up-label").hidden = !this.tool.takes.has("height") && !this.tool.paint;
    this.$("paint-color-row").hidden = !this.tool.takes.has("color");
  }

  #globalOpChanged() {
    const spec = GLOBAL_OPS[this.$("global-op").value];
    this.$("global-amount-row").hidden = !spec;
    if (!spec) return; // a mask operation: no amount
    const amount = this.$("global-amount");
    this.$("global-amount-name").textContent = spec.amount;
    amount.min = String(spec.min);
    amount.max = String(spec.max);
    amount.step = String(spec.step);
    amount.value = String(spec.value);
  }

  // Enables or disables what needs a connection, edit rights, or history. A view-only client
  // keeps View and Files (and they are not marked disabled); its sculpting controls are off and
  // a badge in the top bar says why.
  setAvailability({ connected, readOnly, canUndo, canRedo, volumeFormats = ["mzv"] }) {
    const edit = connected && !readOnly;
    const $ = this.$;
    for (const id of ["global-apply", "load-volume"]) $(id).disabled = !edit;
    $("load-volume-label").setAttribute("aria-disabled", String(!edit));
    $("undo").disabled = $("quick-undo").disabled = !edit || !canUndo;
    $("redo").disabled = $("quick-redo").disabled = !edit || !canRedo;
    $("quickbar").hidden = Boolean(readOnly);
    for (const b of this.doc.querySelectorAll("[data-export]")) b.disabled = !connected;
    for (const id of ["save-volume", "save-vdb", "stats-refresh", "share"]) $(id).disabled = !connected;
    // .vdb only where the server was built with OpenVDB.
    const vdb = volumeFormats.includes("vdb");
    $("save-vdb").hidden = !vdb;
    $("load-volume").accept = vdb ? ".mzv,.vdb" : ".mzv";
    $("load-volume-text").textContent = vdb ? "Load .mzv/.vdb" : "Load .mzv";
    for (const id of ["tool-palette", "brush", "global", "history"]) {
      $(id).disabled = Boolean(readOnly);
      $(id).setAttribute("aria-disabled", String(!edit));
    }
    $("role-badge").hidden = !readOnly;
    this.doc.querySelector(".panel").removeAttribute("aria-disabled");
  }
}

function hexOf(rgb) {
  return `#${rgb.map((c) => c.toString(16).padStart(2, "0")).join("")}`;
}

function rgbOf(hex) {
  return [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
}
