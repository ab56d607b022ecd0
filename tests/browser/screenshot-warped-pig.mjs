// Warps the pig through the web client with the mouse (issue 29's tools) and saves the canvas
// as web-client/images/warped-pig.png (a picture of web-client/README.md): a grab pulls its
// right ear up, a snake hook draws out its tail, a twist turns its snout.
// Usage: MARZIPAN=build/server/marzipan node tests/browser/screenshot-warped-pig.mjs [OUT.png]
// Conventions: positions are fractions of the canvas (x right, y down) in the client's default
// view of the 128^3 pig, which faces +x; each stroke [tool, radius, path] is dragged through its
// points.

import { writeFileSync } from "node:fs";
import { join } from "node:path";

import { repoRoot, startBrowser, startServer } from "./harness.mjs";

const out = process.argv[2] || join(repoRoot, "web-client/images/warped-pig.png");
const plan = [
  ["grab", 8, [[0.436, 0.27], [0.47, 0.15]]],
  ["snake_hook", 4, [[0.652, 0.293], [0.72, 0.27], [0.77, 0.2], [0.75, 0.13]]],
  ["twist", 12, [[0.242, 0.55], [0.3, 0.55]]],
];
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
    }, null, { timeout: 120000 });
  await page.waitForFunction(() => Number(document.getElementById("stat-points").dataset.points || 0) > 0);
  await settle();
  const box = await page.locator("#view").boundingBox();
  const at = (fx, fy) => [box.x + fx * box.width, box.y + fy * box.height];
  for (const [tool, radius, points] of plan) {
    await page.click(`label:has(input[value="${tool}"])`);
    await page.locator("#radius").fill(String(radius));
    const path = points.map(([fx, fy]) => at(fx, fy));
    await page.mouse.move(...path[0]);
    await page.mouse.down();
    for (let i = 1; i < path.length; ++i)
      for (let k = 1; k <= 6; ++k)
        await page.mouse.move(path[i - 1][0] + ((path[i][0] - path[i - 1][0]) * k) / 6, path[i - 1][1] + ((path[i][1] - path[i - 1][1]) * k) / 6);
    await page.mouse.up();
    await settle();
  }
  await page.mouse.move(box.x + 5, box.y + 5);
  await page.evaluate(() => (document.getElementById("hint").hidden = true));
  await page.waitForTimeout(500);
  writeFileSync(out, await page.locator("#view").screenshot());
  console.log(`wrote ${out}`);
} finally {
  await browser.close();
  await server.close();
}
