// Sculpts the pig through the web client, as a person would with the mouse, and saves the
// canvas as web-client/images/sculpted-pig.png (the picture of web-client/README.md).
// Usage: MARZIPAN=build/server/marzipan node tests/browser/screenshot-pig.mjs [OUT.png]
// Positions: fractions of the canvas in the client's default view (pig-shot.mjs).

import { join } from "node:path";

import { repoRoot } from "./harness.mjs";
import { shootPig } from "./pig-shot.mjs";

await shootPig(process.argv[2] || join(repoRoot, "web-client/images/sculpted-pig.png"), async ({ page, at, settle, stroke }) => {
  // A low ridge of add-blob along the back: dabs overlap, so a light strength builds it up.
  await stroke("add_blob", 5, [[0.36, 0.33], [0.45, 0.3], [0.55, 0.31]], { strength: 0.5 });
  // Two dimples pressed into the flank and a smoothed belly line.
  await stroke("remove_blob", 5, [[0.44, 0.5], [0.45, 0.51]], { strength: 1 });
  await stroke("remove_blob", 5, [[0.52, 0.51], [0.53, 0.52]], { strength: 1 });
  await stroke("smooth", 8, [[0.36, 0.58], [0.46, 0.62], [0.56, 0.6]], { strength: 1 });
  // Ears mirrored across z: one stroke sharpens both.
  await page.check("#mirror-z");
  await stroke("sharpen", 6, [[0.63, 0.25], [0.64, 0.27]], { strength: 1 });
  await page.uncheck("#mirror-z");
  // A knob on the rump: CSG add of a blended sphere where the click meets the surface.
  await page.click('label:has(input[value="csg_add"])');
  await page.locator("#radius").fill("5");
  await page.locator("#strength").fill("0.4");
  await page.mouse.click(...at(0.33, 0.38));
  await settle();
});
