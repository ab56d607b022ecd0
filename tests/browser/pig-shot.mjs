// What the screenshot scripts share (screenshot-pig.mjs, screenshot-warped-pig.mjs): their own
// server and Chromium, the 128^3 pig opened in the web client, drags through the page as a
// person would make them with the mouse, and the canvas saved as a PNG.
// Conventions: positions are fractions of the canvas (x right, y down) in the client's default
// view of the 128^3 pig, which faces +x, to the right of the picture.

import { writeFileSync } from "node:fs";

import { startBrowser, startServer } from "./harness.mjs";

// Runs sculpt(pig) on a fresh pig page and writes the canvas to `out`. pig = {page, at(fx, fy)
// (page pixels), settle(), stroke(tool, radius, points, {strength, steps})}.
export async function shootPig(out, sculpt) {
  const server = await startServer();
  const browser = await startBrowser({ width: 1180, height: 760 });
  try {
    const page = await browser.context.newPage();
    await page.goto(`${server.url}/`);
    await page.selectOption("#create-size", "128");
    await page.selectOption("#create-solid", "pig");
    await page.click("#create-button");
    // Settled: the splats drawn are of the newest revision and no stroke is in flight.
    const settle = () =>
      page.waitForFunction(() => {
        const $ = (id) => document.getElementById(id);
        return $("stat-points").dataset.revision === $("revision").dataset.revision && ($("view").dataset.strokes || "0") === "0";
      }, null, { timeout: 120000 });
    await page.waitForFunction(() => Number(document.getElementById("stat-points").dataset.points || 0) > 0);
    await settle();
    const box = await page.locator("#view").boundingBox();
    const at = (fx, fy) => [box.x + fx * box.width, box.y + fy * box.height];
    // One drag through the points, each leg in `steps` pointer moves.
    const stroke = async (tool, radius, points, { strength, steps = 8 } = {}) => {
      await page.click(`label:has(input[value="${tool}"])`);
      await page.locator("#radius").fill(String(radius));
      if (strength !== undefined) await page.locator("#strength").fill(String(strength));
      const path = points.map(([fx, fy]) => at(fx, fy));
      await page.mouse.move(...path[0]);
      await page.mouse.down();
      for (let i = 1; i < path.length; ++i)
        for (let k = 1; k <= steps; ++k)
          await page.mouse.move(path[i - 1][0] + ((path[i][0] - path[i - 1][0]) * k) / steps, path[i - 1][1] + ((path[i][1] - path[i - 1][1]) * k) / steps);
      await page.mouse.up();
      await settle();
    };
    await sculpt({ page, at, settle, stroke });
    await page.mouse.move(box.x + 5, box.y + 5); // no brush cursor in the picture
    await page.evaluate(() => (document.getElementById("hint").hidden = true));
    await page.waitForTimeout(500);
    writeFileSync(out, await page.locator("#view").screenshot());
    console.log(`wrote ${out}`);
  } finally {
    await browser.close();
    await server.close();
  }
}
