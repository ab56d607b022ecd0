// The indicators of the top bar and the session details panel.
// connection: connecting / connected / reconnecting (with the attempt and delay) / offline;
// latency: median round trip of the last RTT_SAMPLES quick requests, in ms; fps: frames drawn in the
// last second and the CPU time of the last draw (idle when nothing is drawn: the page only
// draws when something changes); revision and digest of the session; the clients in it.

const RTT_SAMPLES = 20;
const SLOW_METHODS = new Set([
  "session.create",
  "session.join",
  "session.stats",
  "volume.morph",
  "render.frame",
  "mesh.export",
  "volume.save",
  "volume.load",
  "analysis.thickness",
]);

export class StatusBar {
  constructor(doc) {
    const $ = (id) => doc.getElementById(id);
    this.$ = $;
    this.rtts = [];
    this.medianRtt = null;
  }

  connection({ state, attempt, delayMs }) {
    const el = this.$("connection");
    el.dataset.state = state;
    el.textContent =
      state === "connected" ? "connected"
      : state === "connecting" ? "connecting…"
      : state === "reconnecting" ? (delayMs ? `reconnecting in ${(delayMs / 1000).toFixed(1)} s (attempt ${attempt})` : `reconnecting (attempt ${attempt})…`)
      : "offline";
  }

  // The round trip of a request to `method`. Requests whose answer waits for heavy work
  // (whole-volume operations, files, renders, measures, joining) say nothing about the
  // connection and are left out.
  rtt(method, ms) {
    if (SLOW_METHODS.has(method)) return;
    this.rtts.push(ms);
    if (this.rtts.length > RTT_SAMPLES) this.rtts.shift();
    const sorted = [...this.rtts].sort((a, b) => a - b);
    this.medianRtt = sorted[Math.floor(sorted.length / 2)];
    this.$("latency").textContent = `${this.medianRtt < 10 ? this.medianRtt.toFixed(1) : Math.round(this.medianRtt)} ms`;
  }

  fps(fps, drawMs) {
    this.$("fps").textContent = fps > 0 ? `${Math.round(fps)} fps · ${drawMs.toFixed(1)} ms` : "idle";
  }

  session(info) {
    this.$("stat-session").textContent = `${info.session}${info.read_only ? " (view only)" : ""}`;
    this.$("stat-size").textContent = info.size.join(" × ");
  }

  state({ revision, digest }) {
    this.$("revision").textContent = `rev ${revision}`;
    this.$("revision").dataset.revision = String(revision);
    this.$("stat-digest").textContent = digest || "—";
  }

  clients(clients, self) {
    const others = clients.filter((c) => c.client !== self);
    const names = clients.map((c) => `${c.name || `#${c.client}`}${c.client === self ? " (you)" : ""}${c.read_only ? " viewing" : ""}`);
    const el = this.$("clients");
    el.textContent = others.length ? `${clients.length} here` : "only you";
    el.title = `Clients in this session: ${names.join(", ")}`;
    el.dataset.count = String(clients.length);
  }

  splats(pointCount, brickCount, revision) {
    this.$("stat-points").textContent = `${pointCount.toLocaleString("en")} points in ${brickCount} bricks (rev ${revision})`;
    this.$("stat-points").dataset.points = String(pointCount);
    this.$("stat-points").dataset.revision = String(revision);
  }

  frame(last, received) {
    this.$("stat-frame").textContent = last
      ? `${received} received; rev ${last.revision}, ${last.width}×${last.height} ${last.format}${last.still ? "" : " (interactive)"}`
      : "—";
    this.$("stat-frame").dataset.received = String(received);
    if (last) this.$("stat-frame").dataset.format = last.format;
  }

  stats(s) {
    const num = (v, digits = 0) => v.toLocaleString("en", { maximumFractionDigits: digits });
    this.$("stat-volume").textContent = `${num(s.inside_volume)} vu³`;
    this.$("stat-area").textContent = `${num(s.surface_area)} vu²`;
    this.$("stat-components").textContent = String(s.components);
    this.$("stat-gradient").textContent = `max ${s.gradient_error.max.toFixed(3)}, mean ${s.gradient_error.mean.toFixed(4)}`;
    this.$("stat-memory").textContent = `${(s.memory_bytes / 1048576).toFixed(1)} MiB volume, ${(s.history_bytes / 1048576).toFixed(1)} MiB history`;
  }

  frameTime(m) {
    const el = this.$("stat-frame-time");
    el.textContent = `${m.meanMs.toFixed(1)} ms mean, ${m.p95Ms.toFixed(1)} ms p95 (${m.points.toLocaleString("en")} points, ${m.width}×${m.height})`;
    el.dataset.meanMs = String(m.meanMs);
  }
}
