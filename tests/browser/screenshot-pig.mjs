// Sculpts the pig through the web client, as a person would with the mouse, and saves the
// canvas as web-client/images/sculpted-pig.png (the picture of web-client/README.md).
// Usage: MARZIPAN=build/server/marzipan node tests/browser/screenshot-pig.mjs [OUT.png]
// Conventions: positions are fractions of the canvas (x right, y down) in the client's default
// view of the 128^3 pig, which faces +x, to the right of the picture.

import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { repoRoot, startBrowser, startServer } from "./harness.mjs";

const out = process.argv[2] || join(repoRoot, "web-client/images/sculpted-pig.png");
const server = await startServer();
const browser = await startBrowser({ width: 1180, height: 760 });
try {
  const page = await browser.context.newPage();
  await page.goto(`${server.url}/`);
  await page.selectOption("#create-size", "128");
  await page.selectOption("#create-solid", "pig");
  await page.click("#create-button");
  const settle = () =>
    page.waitForFunction(() => {
      const $ = (id) => document.getElementById(id);
      return $("stat-points").dataset.revision === $("revision").dataset.revision && ($("view").dataset.strokes || "0") === "0";
    });
  await page.waitForFunction(() => Number(document.getElementById("stat-points").dataset.points || 0) > 0);
  const box = await page.locator("#view").boundingBox();
  const at = (fx, fy) => [box.x + fx * box.width, box.y + fy * box.height];
  const stroke = async (tool, radius, strength, points) => {
    await page.click(`label:has(input[value="${tool}"])`);
    await page.locator("#radius").fill(String(radius));
    await page.locator("#strength").fill(String(strength));
    const path = points.map(([fx, fy]) => at(fx, fy));
    await page.mouse.move(...path[0]);
    await page.mouse.down();
    for (let i = 1; i < path.length; ++i)
      for (let k = 1; k <= 8; ++k)
        await page.mouse.move(path[i - 1][0] + ((path[i][0] - path[i - 1][0]) * k) / 8, path[i - 1][1] + ((path[i][1] - path[i - 1][1]) * k) / 8);
    await page.mouse.up();
    await settle();
  };
  // A low ridge of add-blob along the back: dabs overlap, so a light strength builds it up.
  await stroke("add_blob", 5, 0.5, [[0.36, 0.33], [0.45, 0.3], [0.55, 0.31]]);
  // Two dimples pressed into the flank and a smoothed belly line.
  await stroke("remove_blob", 5, 1, [[0.44, 0.5], [0.45, 0.51]]);
  await stroke("remove_blob", 5, 1, [[0.52, 0.51], [0.53, 0.52]]);
  await stroke("smooth", 8, 1, [[0.36, 0.58], [0.46, 0.62], [0.56, 0.6]]);
  // Ears mirrored across z: one stroke sharpens both.
  await page.check("#mirror-z");
  await stroke("sharpen", 6, 1, [[0.63, 0.25], [0.64, 0.27]]);
  await page.uncheck("#mirror-z");
  // A knob on the rump: CSG add of a blended sphere where the click meets the surface.
  await page.click('label:has(input[value="csg_add"])');
  await page.locator("#radius").fill("5");
  await page.locator("#strength").fill("0.4");
  await page.mouse.click(...at(0.33, 0.38));
  await settle();
  await page.mouse.move(box.x + 5, box.y + 5); // no brush cursor in the picture
  await page.evaluate(() => (document.getElementById("hint").hidden = true));
  await page.waitForTimeout(300);
  writeFileSync(out, await page.locator("#view").screenshot());
  console.log(`wrote ${out}`);
} finally {
  await browser.close();
  await server.close();
}
