// The page's .vdb files against a server built with OpenVDB (tests/openvdb.sh runs this file with
// that build's marzipan; tests/browser/run.sh's default list leaves it out, since the default
// build lists only .mzv, which client.test.mjs checks). What must hold: the server lists "vdb";
// the page offers Save .vdb and takes .vdb in its picker; the saved file is an OpenVDB file that
// loads back to the digest it was saved at; a refused .vdb says so in plain words and changes
// nothing.
// Conventions: as client.test.mjs (artifacts in MARZIPAN_BROWSER_ARTIFACTS).

import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { join } from "node:path";

import { digest, ensureArtifactsDir, revision, serverAndBrowser, settled } from "./harness.mjs";

const artifacts = ensureArtifactsDir();
const env = serverAndBrowser();
const revisionAbove = (page, r) => page.waitForFunction((rev) => Number(document.getElementById("revision").dataset.revision) > rev, r);

test("Save .vdb and Load .vdb where the server lists the format", { timeout: 180000 }, async () => {
  const page = await env.browser.context.newPage();
  const errors = [];
  page.on("pageerror", (e) => errors.push(e.message));
  await page.goto(`${env.server.url}/`);
  await page.selectOption("#create-size", "64");
  await page.click("#create-button");
  await settled(page);

  assert.deepEqual(await page.evaluate(() => window.marzipan.session.info.limits.volume_formats), ["mzv", "vdb"]);
  assert.equal(await page.isVisible("#save-vdb"), true);
  assert.equal(await page.getAttribute("#load-volume", "accept"), ".mzv,.vdb");

  const saved = await digest(page);
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#save-vdb")]);
  assert.match(download.suggestedFilename(), /\.vdb$/);
  const path = join(artifacts, "vdb-saved.vdb");
  await download.saveAs(path);
  assert.equal(readFileSync(path).readUInt32LE(0), 0x56444220, "OpenVDB's magic number");

  const r0 = await revision(page);
  await page.evaluate(() => window.marzipan.session.request("tool.apply", { tool: "add_blob", center: [32, 50, 32], radius: 6 }));
  await revisionAbove(page, r0);
  await settled(page);
  assert.notEqual(await digest(page), saved, "the edit changed the volume");

  const r1 = await revision(page);
  await page.setInputFiles("#load-volume", path);
  await revisionAbove(page, r1);
  await settled(page);
  assert.equal(await digest(page), saved, "loading the saved .vdb restores its volume");

  // Not a .vdb: the page says what the file is not, the protocol's words tucked away.
  const r2 = await revision(page);
  await page.setInputFiles("#load-volume", { name: "bad.vdb", mimeType: "application/octet-stream", buffer: Buffer.alloc(200, 7) });
  const message = page.locator(".message.error", { hasText: "volume.load" });
  await message.waitFor();
  assert.match(await message.locator("p").textContent(), /OpenVDB/, "said in plain words, naming the format");
  assert.match(await message.locator("details code").textContent(), /-32006/);
  assert.equal(await revision(page), r2, "a refused load changes nothing");
  assert.equal(await digest(page), saved);
  assert.deepEqual(errors, []);
  await page.close();
});
