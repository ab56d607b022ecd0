// What the browser tests and scripts share: a `marzipan serve` process on a free port, and
// Debian's Chromium driven by playwright-core with a fresh profile.
// Conventions: MARZIPAN (the marzipan executable), CHROMIUM (the browser binary) and
// MARZIPAN_BROWSER_ARTIFACTS (where screenshots and downloads go) come from the environment,
// with this checkout's defaults; both processes are ended by the returned close functions.

import assert from "node:assert/strict";
import { spawn } from "node:child_process";
import { mkdirSync, mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { after, before } from "node:test";
import { chromium } from "playwright-core";

export const repoRoot = resolve(dirname(fileURLToPath(import.meta.url)), "../..");
export const marzipanPath = process.env.MARZIPAN || join(repoRoot, "build/server/marzipan");
export const chromiumPath = process.env.CHROMIUM || "/usr/lib/chromium/chromium";
export const artifactsDir = process.env.MARZIPAN_BROWSER_ARTIFACTS || join(repoRoot, "build/browser-artifacts");

// Flags for headless Chromium on a machine without a GPU or network: SwiftShader's WebGL2, and
// none of the background traffic that a closed network refuses.
export const CHROMIUM_ARGS = [
  "--headless=new",
  "--no-sandbox",
  "--use-angle=swiftshader",
  "--enable-unsafe-swiftshader",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
  "--no-first-run",
];

// Starts `marzipan serve --port 0` with the web client of this checkout; resolves with
// {url, close, log()} once it prints "listening on http://HOST:PORT".
export function startServer(extraArgs = []) {
  const args = ["serve", "--port", "0", "--web-root", join(repoRoot, "web-client"), "--protocol-js", join(repoRoot, "protocol/js"), ...extraArgs];
  const child = spawn(marzipanPath, args, { stdio: ["ignore", "pipe", "pipe"] });
  let stderr = "";
  child.stderr.on("data", (d) => {
    stderr = (stderr + d).slice(-20000);
  });
  const exited = new Promise((res) => child.on("exit", (code, signal) => res({ code, signal })));
  return new Promise((resolvePromise, reject) => {
    let out = "";
    const timer = setTimeout(() => {
      child.kill("SIGKILL");
      reject(new Error(`marzipan serve printed no "listening on" within 20 s; stderr:\n${stderr}`));
    }, 20000);
    child.on("error", (e) => {
      clearTimeout(timer);
      reject(new Error(`cannot start ${marzipanPath}: ${e.message}`));
    });
    child.on("exit", (code) => {
      clearTimeout(timer);
      reject(new Error(`marzipan serve exited with ${code} before listening; stderr:\n${stderr}`));
    });
    child.stdout.on("data", (d) => {
      out += d;
      const m = out.match(/listening on (http:\/\/\S+)/);
      if (!m) return;
      clearTimeout(timer);
      resolvePromise({
        url: m[1].replace(/\/$/, ""),
        log: () => stderr,
        async close() {
          child.kill("SIGTERM");
          const t = setTimeout(() => child.kill("SIGKILL"), 5000);
          const r = await exited;
          clearTimeout(t);
          return r;
        },
      });
    });
  });
}

// A screen of a quarter of a pixel per CSS pixel, for what reads no pixels: the page's layout,
// its camera and every position in CSS pixels are those of density 1, its canvas has a
// sixteenth of the device pixels. Headless Chromium draws WebGL with SwiftShader on the CPU, and
// a pointer move over the canvas waits for the frame its brush cursor asks: the 128³ sphere at
// 1100 × 760 took 0.52 s a frame at density 1, 0.21 s at 0.5 and 0.11 s at 0.25 on the 2-core VM
// (2026-11-30), and collab.test.mjs 106 s at 0.5, 70 s at 0.25.
export const LOW_DENSITY = 0.25;

// Chromium with a fresh profile directory; resolves with {context, close}. The context saves
// downloads and allows them; hasTouch gives its pages a touch screen besides the mouse;
// localStorage holds items every page of the context finds in its storage from the start.
export async function startBrowser({ width = 1100, height = 760, deviceScaleFactor = 1, hasTouch = false, localStorage = {} } = {}) {
  const profile = mkdtempSync(join(tmpdir(), "marzipan-chromium-"));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: chromiumPath,
    headless: true,
    args: CHROMIUM_ARGS,
    viewport: { width, height },
    deviceScaleFactor,
    hasTouch,
    acceptDownloads: true,
  });
  if (Object.keys(localStorage).length)
    await context.addInitScript((items) => {
      if (!location.protocol.startsWith("http")) return; // about:blank has no storage of its own
      for (const [key, value] of Object.entries(items)) window.localStorage.setItem(key, value);
    }, localStorage);
  return {
    context,
    async close() {
      await context.close();
      rmSync(profile, { recursive: true, force: true });
    },
  };
}

export function ensureArtifactsDir() {
  mkdirSync(artifactsDir, { recursive: true });
  return artifactsDir;
}

// Waits until the session is connected, the splats shown are those of the session's revision
// and no stroke is still on the wire: the picture is settled.
export async function settled(page, timeout = 60000) {
  await page.waitForFunction(
    () => {
      const $ = (id) => document.getElementById(id);
      const rev = $("revision").dataset.revision;
      return (
        $("connection").dataset.state === "connected" &&
        Number($("stat-points").dataset.points || 0) > 0 &&
        $("stat-points").dataset.revision === rev &&
        ($("view").dataset.strokes || "0") === "0"
      );
    },
    null,
    { timeout },
  );
  await drawn(page); // the redraw after the last splats is one animation frame away
}

// Resolves once the page has drawn a frame begun after this call: the renderer draws in a
// requestAnimationFrame callback, so a redraw requested before this has run by the time the
// second of two such callbacks runs, however late a loaded machine makes the frames. After a
// fixed wait, it makes sure that the picture taken next is the one asked for.
export async function drawn(page) {
  await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
}

// A test file's server and browser: started before its first test, closed after its last, the
// server required to exit cleanly. The returned object's `server` and `browser` are set once the
// tests run.
export function serverAndBrowser(browserOptions = {}) {
  const env = { server: null, browser: null };
  before(async () => {
    env.server = await startServer();
    env.browser = await startBrowser(browserOptions);
  });
  after(async () => {
    if (env.browser) await env.browser.close();
    if (env.server) {
      const { code, signal } = await env.server.close();
      assert.equal(code, 0, `marzipan serve exited with ${code} (${signal}); its log:\n${env.server.log()}`);
    }
  });
  return env;
}

// The page's session revision and digest as its status bar shows them.
export const revision = async (page) => Number(await page.evaluate(() => document.getElementById("revision").dataset.revision));
export const digest = (page) => page.locator("#stat-digest").textContent();
